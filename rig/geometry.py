"""Directions on the hemisphere above the sample, and the samplings of it.

Conventions (drawn in ``docs/geometry.md``): the *sample frame* is right-handed,
z is the sample normal, x runs along the sample's first texture axis. A
direction is given by θ, the polar angle from +z, and φ, the azimuth from +x
towards +y, both in degrees, φ in [0, 360). Directions point away from the
surface: towards the camera (view) or towards the lamp (light).

References
----------
.. [1] Sattler, Sarlette, Klein. "Efficient and realistic visualization of
   cloth." EGSR 2003, Table 1 (samplings H1 and H2).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from scipy.spatial import ConvexHull, QhullError, cKDTree

from rig.errors import ConfigError

__all__ = [
    "LIGHT_COSINE_FLOOR",
    "Interpolation",
    "Sampling",
    "SphericalTriangulation",
    "angular_distance_deg",
    "barycentric_weights",
    "carry_light_cosine",
    "direction_angles",
    "direction_vector",
    "nearest_directions",
    "spherical_triangulation",
    "texel_centers_mm",
]


def direction_vector(theta_deg, phi_deg) -> np.ndarray:
    """Unit vectors for directions (θ, φ) in degrees.

    Returns
    -------
    (..., 3) float64
        ``(sinθ cosφ, sinθ sinφ, cosθ)``, broadcast over the inputs.
    """
    theta, phi = np.broadcast_arrays(
        np.deg2rad(np.asarray(theta_deg, dtype=np.float64)),
        np.deg2rad(np.asarray(phi_deg, dtype=np.float64)),
    )
    sin_t = np.sin(theta)
    return np.stack([sin_t * np.cos(phi), sin_t * np.sin(phi), np.cos(theta)], axis=-1)


def direction_angles(vectors) -> tuple[np.ndarray, np.ndarray]:
    """(θ, φ) in degrees of direction vectors (need not be unit length).

    φ is in [0, 360); at the pole (θ = 0) φ is reported as 0. A zero vector
    raises ``ValueError`` because it has no direction.
    """
    v = np.asarray(vectors, dtype=np.float64)
    norm = np.linalg.norm(v, axis=-1)
    if np.any(norm == 0):
        raise ValueError("direction_angles: a zero vector has no direction")
    z = np.clip(v[..., 2] / norm, -1.0, 1.0)
    theta = np.rad2deg(np.arccos(z))
    phi = np.rad2deg(np.arctan2(v[..., 1], v[..., 0])) % 360.0
    at_pole = np.hypot(v[..., 0], v[..., 1]) <= 1e-12 * norm
    phi = np.where(at_pole, 0.0, phi)
    # % 360 can return 360.0 for tiny negative angles; fold it back.
    phi = np.where(phi >= 360.0, 0.0, phi)
    return theta, phi


def angular_distance_deg(a, b) -> np.ndarray:
    """Angle in degrees between direction vectors ``a`` and ``b`` (broadcast)."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    a = a / np.linalg.norm(a, axis=-1, keepdims=True)
    b = b / np.linalg.norm(b, axis=-1, keepdims=True)
    # atan2 of |a×b| and a·b stays accurate for tiny and near-180° angles.
    cross = np.linalg.norm(np.cross(a, b), axis=-1)
    dot = np.sum(a * b, axis=-1)
    return np.rad2deg(np.arctan2(cross, dot))


# Table 1 of Sattler et al. 2003: (θ, Δφ) per ring; Δφ = 0 marks the single
# frontal sample at φ = 0.
_RINGS = {
    "H1": ((0, 0), (17, 60), (34, 30), (51, 20), (68, 18), (85, 15)),
    "H2": ((0, 0), (15, 60), (30, 30), (45, 20), (60, 18), (75, 15)),
}


#: Two directions closer than this are the same direction.
_SAME_DIRECTION_DEG = 1e-6


def _first_duplicate(vectors: np.ndarray) -> tuple[int, int] | None:
    """The first pair ``(i, j)``, ``i < j``, of unit vectors closer than
    ``_SAME_DIRECTION_DEG``, in row order; None when all differ.

    A KD-tree finds the candidates within the chord of that angle (slightly
    widened for rounding) in O(n log n); the angle itself decides.
    """
    chord = 2.0 * np.sin(np.deg2rad(_SAME_DIRECTION_DEG) / 2.0)
    pairs = cKDTree(vectors).query_pairs(chord * (1.0 + 1e-6) + 1e-15, output_type="ndarray")
    if len(pairs) == 0:
        return None
    angles = angular_distance_deg(vectors[pairs[:, 0]], vectors[pairs[:, 1]])
    close = pairs[angles < _SAME_DIRECTION_DEG]
    if len(close) == 0:
        return None
    i, j = close[np.lexsort((close[:, 1], close[:, 0]))[0]]
    return int(i), int(j)


@dataclass(frozen=True)
class Sampling:
    """An ordered set of directions on the upper hemisphere.

    Parameters
    ----------
    name : str
        ``"H1"``, ``"H2"`` or a user's label for a custom sampling.
    directions : (n, 2) float64
        (θ, φ) in degrees, θ in [0, 90], φ in [0, 360).
    """

    name: str
    directions: np.ndarray

    def __post_init__(self) -> None:
        d = np.asarray(self.directions, dtype=np.float64)
        if d.ndim != 2 or d.shape[1] != 2 or len(d) == 0:
            raise ConfigError(
                f"sampling {self.name!r}: directions must be a non-empty list of "
                f"[theta_deg, phi_deg] pairs, got shape {d.shape}"
            )
        if not np.all(np.isfinite(d)):
            raise ConfigError(f"sampling {self.name!r}: directions contain NaN or inf")
        bad = np.flatnonzero((d[:, 0] < 0) | (d[:, 0] > 90))
        if len(bad):
            i = int(bad[0])
            raise ConfigError(
                f"sampling {self.name!r}: direction {i} has theta {d[i, 0]}°, "
                "valid is 0 ≤ theta ≤ 90 (the upper hemisphere)"
            )
        d = d.copy()
        d[:, 1] %= 360.0
        d[d[:, 0] == 0, 1] = 0.0
        duplicate = _first_duplicate(direction_vector(d[:, 0], d[:, 1]))
        if duplicate is not None:
            i, j = duplicate
            raise ConfigError(
                f"sampling {self.name!r}: directions {i} and {j} are the same "
                f"({d[i, 0]}°, {d[i, 1]}°); each direction must appear once"
            )
        d.setflags(write=False)
        object.__setattr__(self, "directions", d)

    @classmethod
    def named(cls, name: str) -> Sampling:
        """The seed's H1 or H2 sampling: 81 directions in 6 rings."""
        try:
            rings = _RINGS[name]
        except KeyError:
            raise ConfigError(
                f"unknown sampling {name!r}; valid names are {sorted(_RINGS)} "
                "or a custom list of [theta_deg, phi_deg] directions"
            ) from None
        dirs = []
        for theta, dphi in rings:
            phis = [0.0] if dphi == 0 else np.arange(0.0, 360.0, dphi)
            dirs.extend((theta, phi) for phi in phis)
        return cls(name, np.array(dirs))

    def __len__(self) -> int:
        return len(self.directions)

    @cached_property
    def vectors(self) -> np.ndarray:
        """(n, 3) float64 unit vectors of the directions."""
        v = direction_vector(self.directions[:, 0], self.directions[:, 1])
        v.setflags(write=False)
        return v

    def rings(self) -> dict[float, np.ndarray]:
        """Indices of the directions grouped by θ, rings in increasing θ."""
        thetas = np.round(self.directions[:, 0], 9)
        return {float(t): np.flatnonzero(thetas == t) for t in np.unique(thetas)}


@dataclass(frozen=True)
class Interpolation:
    """Which table directions to blend for each query, and how much.

    indices : (m, k) int64, weights : (m, k) float64 (rows sum to 1, ≥ 0; a light
    blend then scales them by :func:`carry_light_cosine`),
    angles_deg : (m, k) float64 angle from the query to each chosen direction.
    """

    indices: np.ndarray
    weights: np.ndarray
    angles_deg: np.ndarray


def _as_directions(name: str, vectors) -> np.ndarray:
    v = np.atleast_2d(np.asarray(vectors, dtype=np.float64))
    if v.ndim != 2 or v.shape[1] != 3:
        raise ValueError(f"{name}: expected (n, 3) direction vectors, got shape {v.shape}")
    norm = np.linalg.norm(v, axis=1, keepdims=True)
    if not np.all(np.isfinite(v)) or np.any(norm == 0):
        raise ValueError(f"{name}: direction vectors must be finite and non-zero")
    return v / norm


def nearest_directions(table_vectors, query_vectors, *, k: int = 4) -> Interpolation:
    """The ``k`` nearest table directions of each query, with Shepard weights.

    Weights are inverse squared angles, normalised; a query that coincides with
    a table direction gets weight exactly 1 there, so interpolation is exact at
    measured directions.

    Parameters
    ----------
    table_vectors : (n, 3) array
        Measured directions.
    query_vectors : (m, 3) array
        Wanted directions.
    k : int
        How many neighbours, 1 ≤ k ≤ n (the seed uses 4).
    """
    table = _as_directions("table_vectors", table_vectors)
    query = _as_directions("query_vectors", query_vectors)
    if not 1 <= k <= len(table):
        raise ValueError(f"nearest_directions: k={k}, valid is 1 ≤ k ≤ {len(table)}")
    angles = angular_distance_deg(query[:, None, :], table[None, :, :])
    order = np.argsort(angles, axis=1, kind="stable")[:, :k]
    near = np.take_along_axis(angles, order, axis=1)
    exact = near[:, :1] <= 1e-9
    inv = 1.0 / np.maximum(near, 1e-9) ** 2
    weights = np.where(exact, (np.arange(k) == 0).astype(np.float64), inv)
    weights /= weights.sum(axis=1, keepdims=True)
    return Interpolation(order, weights, near)


#: The smallest cos θ of a measured light that :func:`carry_light_cosine` divides by
#: (θ ≈ 89.4°): a light lying in the sample's plane gives it no irradiance to carry.
LIGHT_COSINE_FLOOR = 1e-2


def carry_light_cosine(found: Interpolation, table_vectors, query_vectors) -> np.ndarray:
    """Weights of a light blend that carry the irradiance's cosine: (m, k) float64.

    A measured texture holds the sample's response times cos θ_i of its light
    (the irradiance a distant light gives the sample's plane), so blending the
    textures of lights at other polar angles blends their cosines too: between
    15° and 45°, 0.97 and 0.71. Each weight is scaled by cos θ_q / cos θ_i, which
    blends the responses and lays the query's own cosine on them (the bumps'
    textures interpolated to directions between the medium plan's lights: 31 → 35 dB
    against the truth, docs/render.md). Exact at a measured light (a weight 1 on it
    keeps 1); zero for a query at or below the horizon; a measured light with
    cos θ_i below :data:`LIGHT_COSINE_FLOOR` divides by the floor. The rows no
    longer sum to 1.

    Parameters
    ----------
    found : the blend of ``query_vectors`` over ``table_vectors``
        (:func:`nearest_directions`, :func:`barycentric_weights`)
    table_vectors : (n, 3) measured light directions
    query_vectors : (m, 3) wanted light directions
    """
    table = _as_directions("table_vectors", table_vectors)
    query = _as_directions("query_vectors", query_vectors)
    cos_query = np.maximum(query[:, 2], 0.0)[:, None]
    cos_table = np.maximum(table[found.indices, 2], LIGHT_COSINE_FLOOR)
    return found.weights * cos_query / cos_table


@dataclass(frozen=True)
class SphericalTriangulation:
    """The spherical triangles that :func:`barycentric_weights` blends over.

    corners : (t, 3, 3) float64 unit vectors of each triangle's corners (a
    corner below the horizon is a table direction mirrored in z = 0),
    owner : (t, 3) int64 the table index of each corner, inverse : (t, 3, 3)
    float64 with ``inverse[t] @ q`` the (unclipped) barycentric weights of a
    query q in triangle t's gnomonic projection.
    """

    corners: np.ndarray
    owner: np.ndarray
    inverse: np.ndarray


def spherical_triangulation(table_vectors) -> SphericalTriangulation:
    """Triangulate table directions on the sphere, mirrored below the horizon.

    The convex hull of the table and its mirror image in z = 0, so queries
    near θ = 90° lie in a triangle too. ValueError for fewer than 3 directions
    or directions on one great circle.
    """
    table = _as_directions("table_vectors", table_vectors)
    n = len(table)
    if n < 3:
        raise ValueError(f"barycentric_weights: need ≥ 3 table directions, got {n}")
    mirrored = table * np.array([1.0, 1.0, -1.0])
    keep = table[:, 2] > 1e-9  # directions on the horizon are their own mirror
    points = np.vstack([table, mirrored[keep]])
    owner = np.concatenate([np.arange(n), np.flatnonzero(keep)])
    try:
        hull = ConvexHull(points)
    except QhullError as err:
        raise ValueError(
            "barycentric_weights: the table directions do not span the hemisphere "
            "(all on one great circle?)"
        ) from err
    tri = hull.simplices  # (t, 3)
    corners = points[tri]  # (t, 3 corners, 3 xyz)
    # corners^T w = q for every triangle: w = inverse q.
    inverse = np.linalg.pinv(np.transpose(corners, (0, 2, 1)))
    return SphericalTriangulation(corners, owner[tri], inverse)


def barycentric_weights(table_vectors, query_vectors) -> Interpolation:
    """Blend the 3 table directions of the spherical triangle holding each query.

    The table is triangulated on the sphere (:func:`spherical_triangulation`:
    the convex hull, with the table mirrored below the horizon so queries near
    θ = 90° are covered); weights are the barycentric coordinates of the query
    in the gnomonic projection of its triangle. Weights are linear-precise
    within a triangle, continuous across edges and exact at table directions.
    """
    table = _as_directions("table_vectors", table_vectors)
    query = _as_directions("query_vectors", query_vectors)
    mesh = spherical_triangulation(table)
    w = np.einsum("tij,mj->mti", mesh.inverse, query)  # (m, t, 3)
    best = np.argmax(w.min(axis=2), axis=1)  # the triangle the ray passes through
    wq = np.clip(w[np.arange(len(query)), best], 0.0, None)
    wq /= wq.sum(axis=1, keepdims=True)
    idx = mesh.owner[best]
    angles = angular_distance_deg(query[:, None, :], table[idx])
    return Interpolation(idx, wq, angles)


def texel_centers_mm(sample_mm: float, n: int) -> np.ndarray:
    """Sample-frame (x, y) in mm of the centres of an n×n texel grid.

    The grid covers the sample square [-s/2, s/2]² on the reference plane
    z = 0 (the holder's top, flush with the highest point of the sample).
    Row 0 is at +y, column 0 at -x, like an image seen from above, so
    ``texel[r, c]`` lies at ``x = -s/2 + (c + ½)·s/n``, ``y = s/2 - (r + ½)·s/n``.
    Normtextures, MDFs and photometric maps all use this grid.

    Returns
    -------
    (n, n, 2) float64
    """
    if n < 1 or sample_mm <= 0:
        raise ValueError(f"texel_centers_mm: need n ≥ 1 and sample_mm > 0, got {n}, {sample_mm}")
    step = sample_mm / n
    coords = -sample_mm / 2 + (np.arange(n) + 0.5) * step
    xx, yy = np.meshgrid(coords, coords[::-1])
    return np.stack([xx, yy], axis=-1)
