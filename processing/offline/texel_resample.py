"""Each texel's samples, measured at its own directions, resampled onto the plan's.

A near device turns its direction across the sample: a camera 800 mm away sees
each texel from its own view direction, a lamp 650 mm away lights each texel
from its own light direction. Where a table of S nominal directions (the plan's
view slots, or one slot's lights) was measured at a texel from S directions of
its own, the value at nominal direction j is the barycentric blend, on the
sphere, of the texel's samples at the corners of the triangle that holds j (the
triangulation of the nominal directions, seed 000 eq. (5), with the texel's own
directions as its corners). The weights w_k of corners d_k solve
Σ w_k d_k = q for the nominal direction q and reproduce exactly (``exact_for``):

- ``"constant"``: w normalised to sum to 1 (seed 000's barycentric weights): a value
  the direction does not change, as a Lambertian texel's radiance over views;
- ``"linear"``: w as solved: a value linear in the direction vector, as a Lambertian
  texel's ρ/π n·l per unit irradiance of a distant light over lights. The
  triangles are tens of degrees across while a texel's directions turn by a few:
  blended with weights normalised, such a value is off by 1 − |Σ ŵ_k d_k|
  (about 2 % across the coarse plan's 45° triangles), as much as the turn changes it.

Where a texel's own directions do not surround the nominal one (outside the
hull of what that texel was measured at: the holding triangle reaches below the
horizon through the triangulation's mirror, or a weight is negative), nothing
is invented: the texel keeps its own sample, weight 1, and is flagged.
:mod:`processing.offline.texel_view` uses it for views,
:mod:`processing.offline.texel_light` for lights.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rig.geometry import direction_vector, spherical_triangulation, texel_centers_mm

__all__ = ["EXACT_FOR", "TexelResampling", "blended", "texel_directions", "texel_resampling"]

#: Weights above −this count as inside a triangle (rounding on its edges).
_EDGE_TOL = 1e-9


@dataclass(frozen=True)
class TexelResampling:
    """How each texel's sample at each nominal direction is blended from its own.

    indices : (S, n, n, 3) int — the own samples blended (positions in the table)
    weights : (S, n, n, 3) float64 — their weights (``exact_for``: summing to 1, or
        blending the corners' directions into the nominal one)
    outside : (S, n, n) bool — the nominal direction is outside the texel's own hull:
        weight 1 on its own sample (kept as measured)
    turn_deg : (S, n, n) float64 — angle between the texel's own and the nominal direction
    """

    indices: np.ndarray
    weights: np.ndarray
    outside: np.ndarray
    turn_deg: np.ndarray


def texel_directions(point_mm: np.ndarray, sample_mm: float, size: int) -> np.ndarray:
    """(size, size, 3) unit vectors from each texel centre (on z = 0) to a point
    ``point_mm`` (3,) (a camera's centre, a lamp), sample frame, mm."""
    points = np.concatenate([texel_centers_mm(sample_mm, size), np.zeros((size, size, 1))], -1)
    rays = np.asarray(point_mm, dtype=np.float64) - points
    return rays / np.linalg.norm(rays, axis=-1, keepdims=True)


#: ``texel_resampling``'s ``exact_for``: the dependences on direction it reproduces.
EXACT_FOR = ("constant", "linear")


def texel_resampling(
    nominal_deg: np.ndarray, own: np.ndarray, *, exact_for: str = "constant"
) -> TexelResampling:
    """Blend weights that move every texel's samples onto the nominal directions.

    Parameters
    ----------
    nominal_deg : (S, 2) the table's nominal (θ, φ) directions, degrees, S ≥ 3 not on
        one great circle (else ValueError)
    own : (S, n, n, 3) unit vectors, each texel's own direction per table entry
        (:func:`texel_directions`), above the horizon
    exact_for : ``"constant"`` or ``"linear"`` (:data:`EXACT_FOR`, module docstring)

    Returns
    -------
    TexelResampling
    """
    if exact_for not in EXACT_FOR:
        raise ValueError(f"texel_resampling exact_for = {exact_for!r}: valid are "
                         f"{list(EXACT_FOR)}")  # fmt: skip
    nominal = direction_vector(nominal_deg[:, 0], nominal_deg[:, 1])
    mesh = spherical_triangulation(nominal)  # the topology: the nominal table's
    owner = mesh.owner  # (T, 3) table entry of each corner
    mirrored = mesh.corners[..., 2] < 0.0  # (T, 3) corners below the horizon
    flip = np.where(mirrored[..., None], np.array([1.0, 1.0, -1.0]), 1.0)  # (T, 3, 3)
    # each texel's triangles: its own directions at the nominal corners (mirrored alike)
    corners = own[owner] * flip[:, :, None, None, :]  # (T, 3, n, n, 3)
    corners = np.moveaxis(corners, 1, 3)  # (T, n, n, 3 corners, 3 xyz)
    inverse = _corner_inverse(corners)  # w = inverse · q
    n = own.shape[1]
    entries = len(nominal)
    indices = np.empty((entries, n, n, 3), np.int64)
    weights = np.empty((entries, n, n, 3))
    outside = np.empty((entries, n, n), bool)
    for j in range(entries):
        near = _around(owner, j)
        w = inverse[near] @ nominal[j]  # (t, n, n, 3)
        best = np.argmax(w.min(axis=-1), axis=0)  # (n, n) the triangle holding it
        wq = np.take_along_axis(w, best[None, ..., None], axis=0)[0]
        best = near[best]
        below = (mirrored[best] & (wq > _EDGE_TOL)).any(axis=-1)
        out = below | (wq.min(axis=-1) < -_EDGE_TOL)
        wq = np.clip(wq, 0.0, None)
        if exact_for == "constant":
            wq /= wq.sum(axis=-1, keepdims=True)
        indices[j] = np.where(out[..., None], j, owner[best])
        weights[j] = np.where(out[..., None], np.array([1.0, 0.0, 0.0]), wq)
        outside[j] = out
    turn = np.degrees(np.arccos(np.clip(np.einsum("snmk,sk->snm", own, nominal), -1.0, 1.0)))
    return TexelResampling(indices, weights, outside, turn)


def _around(owner: np.ndarray, j: int) -> np.ndarray:
    """Indices of the triangles within two rings of table entry ``j`` (sharing a corner
    with a triangle that has ``j`` as a corner, mirrored corners included): a texel's own
    directions turn each entry by a few degrees, far less than a triangle is wide, so
    the triangle of the texel's own that holds nominal ``j`` is one of these. Were it not,
    no triangle here would hold ``j`` and the texel would be kept as measured and
    counted (``outside``), never blended from a wrong triangle."""
    star = np.flatnonzero((owner == j).any(axis=1))
    corners = np.unique(owner[star])
    return np.flatnonzero(np.isin(owner, corners).any(axis=1))


#: A triangle whose corners' determinant is under this (three unit vectors nearly on one
#: great circle) is inverted by the pseudo-inverse instead of the cofactors.
_SINGULAR = 1e-9


def _corner_inverse(corners: np.ndarray) -> np.ndarray:
    """(…, 3 weights, 3 xyz): the inverse of each triangle's corner matrix (columns the
    corners a, b, c), so that its weights for a direction q are ``inverse @ q``. Rows
    b × c, c × a, a × b over the determinant: a 3 × 3 SVD per texel and triangle cost
    seconds per slot; the pseudo-inverse only where the corners are (nearly) coplanar."""
    a, b, c = corners[..., 0, :], corners[..., 1, :], corners[..., 2, :]
    rows = np.stack([np.cross(b, c), np.cross(c, a), np.cross(a, b)], axis=-2)
    det = np.einsum("...k,...k->...", a, rows[..., 0, :])
    flat = np.abs(det) < _SINGULAR
    inverse = rows / np.where(flat, 1.0, det)[..., None, None]
    if flat.any():
        inverse[flat] = np.linalg.pinv(np.swapaxes(corners[flat], -1, -2))
    return inverse


def blended(plan: TexelResampling, j: int, samples: dict[int, np.ndarray]) -> np.ndarray:
    """(…, n, n, C) float32: every texel's value at nominal direction ``j``.

    ``samples``: table entry k → (…, n, n, C) float32, the texels' samples at their
    own direction k (any leading axes, e.g. a view slot's lights), for every k in
    ``plan.indices[j]``."""
    blend = np.zeros_like(next(iter(samples.values())))
    for k, values in samples.items():
        w = np.where(plan.indices[j] == k, plan.weights[j], 0.0).sum(axis=-1)  # (n, n)
        blend += values * w[:, :, None].astype(np.float32)
    return blend
