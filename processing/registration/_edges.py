"""Sub-pixel marker corners from straight-line fits to the marker's outer edges.

OpenCV's corner refinement (``cornerSubPix``) is built for saddle points; on
the convex corner of a black marker in a white quiet zone it is biased
outwards by ~0.2 px. Under a homography the marker's outer edges stay
straight, so each edge is located instead: along many normals through the
middle of an edge the grey level is sampled (bilinear) and the edge position
is found from the area under the normalised profile (a moment estimator,
unbiased for any symmetric blur, unlike a half-level crossing of the
interpolated samples, which is off by up to 1/8 px depending on the edge's
sub-pixel phase); a total least-squares line through those positions is
intersected with its neighbours' lines to give the corners.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

__all__ = ["refine_corners"]

_SPAN = (0.15, 0.85)  # the part of each edge used, away from the corners
_STEPS_PER_PX = 8


def _edge_points(
    gray: np.ndarray, p0: np.ndarray, p1: np.ndarray, outward: np.ndarray, reach_px: float
) -> np.ndarray:
    """Edge positions along normals of the edge p0→p1; (k, 2) pixels.

    On each normal the profile f(s) ∈ [0, 1] (0 = black border, 1 = white
    plate) is integrated over [−R, R]; for a step at e blurred by any
    symmetric kernel (the pixel's box among them) ∫ f ds = R − e, so the
    edge lies at e = R − ∫ f ds whatever the sub-pixel phase of the edge.
    """
    length = float(np.linalg.norm(p1 - p0))
    n_normals = max(4, int(length * (_SPAN[1] - _SPAN[0])))
    t = np.linspace(_SPAN[0], _SPAN[1], n_normals)
    n_steps = max(9, int(2 * reach_px * _STEPS_PER_PX) | 1)
    offsets = np.linspace(-reach_px, reach_px, n_steps)
    base = p0[None, :] + t[:, None] * (p1 - p0)[None, :]
    pts = base[:, None, :] + offsets[None, :, None] * outward[None, None, :]
    profile = ndimage.map_coordinates(
        gray, [pts[..., 1].ravel(), pts[..., 0].ravel()], order=1, mode="nearest"
    ).reshape(pts.shape[:2])
    ends = max(1, n_steps // 6)
    # Levels per edge, from the ends of all its normals: less noisy than per normal.
    dark = float(np.median(profile[:, :ends]))
    bright = float(np.median(profile[:, -ends:]))
    if bright - dark <= 0.2 * max(abs(bright), abs(dark), 1e-12):
        return np.zeros((0, 2))
    f = np.clip((profile - dark) / (bright - dark), 0.0, 1.0)
    # Normals crossing something other than one edge (a neighbour's module,
    # the sample) have a wrong end; keep those that start dark and end bright.
    clean = (f[:, :ends].max(axis=1) < 0.25) & (f[:, -ends:].min(axis=1) > 0.75)
    e = reach_px - np.trapezoid(f, offsets, axis=1)
    return (base + e[:, None] * outward[None, :])[clean]


def _fit_line(points: np.ndarray) -> tuple[np.ndarray, float] | None:
    """Total least-squares line n·x = d through (k, 2) points, or None."""
    if len(points) < 3:
        return None
    centre = points.mean(axis=0)
    *_, vt = np.linalg.svd(points - centre, full_matrices=False)
    normal = vt[-1]
    return normal, float(normal @ centre)


def refine_corners(gray: np.ndarray, quad: np.ndarray, *, modules: int) -> np.ndarray | None:
    """Corners of one marker from line fits to its four outer edges.

    Parameters
    ----------
    gray : (H, W) float64
        Grey image (any scale; black marker on a brighter plate).
    quad : (4, 2) float64
        Initial corners (OpenCV order), good to a fraction of a module.
    modules : int
        Modules per marker side including the black border (bits + 2).

    Returns
    -------
    (4, 2) float64 or None
        None where an edge could not be located; the caller keeps ``quad``.
    """
    corners = np.asarray(quad, dtype=np.float64)
    for _ in range(2):
        centre = corners.mean(axis=0)
        lines = []
        for k in range(4):
            p0, p1 = corners[k], corners[(k + 1) % 4]
            direction = (p1 - p0) / max(np.linalg.norm(p1 - p0), 1e-12)
            outward = np.array([direction[1], -direction[0]])
            if outward @ (0.5 * (p0 + p1) - centre) < 0:
                outward = -outward
            # The border's width along this normal: the marker's extent across
            # the edge (the neighbouring edges projected on the normal) / modules.
            far0, far1 = corners[(k + 3) % 4], corners[(k + 2) % 4]
            depth = 0.5 * abs(outward @ (far0 - p0) + outward @ (far1 - p1))
            module_px = depth / modules
            line = _fit_line(_edge_points(gray, p0, p1, outward, 0.8 * module_px))
            if line is None:
                return None
            lines.append(line)
        new = np.empty((4, 2))
        for k in range(4):
            # Corner k joins edge k−1 (from corner k−1) and edge k (to corner k+1).
            (n0, d0), (n1, d1) = lines[k - 1], lines[k]
            A = np.array([n0, n1])
            if abs(np.linalg.det(A)) < 1e-6:
                return None
            new[k] = np.linalg.solve(A, [d0, d1])
        sides = np.linalg.norm(corners - np.roll(corners, 1, axis=0), axis=1)
        if np.max(np.linalg.norm(new - corners, axis=1)) > sides.min() / modules:
            return None
        corners = new
    return corners
