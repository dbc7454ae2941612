"""Displacement image D_{v,l} of one scan on the texel grid.

For a texel with reference point Q = (x, y, 0), the MDF value is the distance
along the view ray from Q down to the first surface hit (seed ``001_…``
section 3; the view ray is the perspective ray from the camera centre through
Q). The camera pixel at Q's projection looks along exactly that ray, so its
space-time peak time says when the laser sheet crossed the surface point the
texel sees. Per neighbouring pixel (the four around Q's projection):

1. take its peak time and the laser plane at that time (interpolated);
2. intersect the pixel's own ray with that plane → its surface point p_j;
3. D_j = (p_j - Q) · d, the depth of p_j along the texel's view direction d;
4. blend the D_j bilinearly over the valid neighbours.

This is bilinear interpolation of the triangulated surface, read along the
texel's ray: exact on planes, second order in curvature elsewhere. If the valid
neighbours' depths disagree by more than ``edge_tol_px`` (a depth or shadow
edge), the nearest valid neighbour alone is used and the texel is marked EDGE.

A plane that makes a small angle with a pixel's ray is GRAZING: a plane error δ
moves the point by δ/|n·d| along the ray, and the point is dropped when that
gain exceeds ``max_error_gain``. With the line located to ~0.05 px, a gain of
10 keeps the plane's share of the error near 0.5 px even in the worst case;
the merge weights favour the well-conditioned locations anyway.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from processing.mdf._errors import MdfError
from processing.mdf._reason import Reason
from processing.mdf.sheet import ScanPlanes
from processing.mdf.spacetime import PixelPeaks
from rig.camera import PinholeCamera

__all__ = ["ScanDisplacement", "displacement_image", "reference_footprint_mm"]


@dataclass(frozen=True)
class ScanDisplacement:
    """D_{v,l}: the displacement image of one view and one laser location.

    Attributes
    ----------
    distance : (N, N) float32
        mm along the view ray from (x, y, 0) to the surface, ≥ 0; -1 where
        ``reason`` is neither OK nor EDGE.
    reason : (N, N) uint8
        :class:`~processing.mdf.Reason` per texel.
    weight : float
        Merge weight of this laser location (tetrahedron volume, mm³).
    """

    distance: np.ndarray
    reason: np.ndarray
    weight: float

    @property
    def valid(self) -> np.ndarray:
        """(N, N) bool: texels with a value."""
        return self.reason <= Reason.EDGE


def reference_footprint_mm(camera: PinholeCamera, texels_xy) -> np.ndarray:
    """Side of one pixel's footprint on the reference plane at each texel, mm.

    ``1 / sqrt(|det J|)`` with J the Jacobian of the projection of the
    reference plane into the image. Divide a length in mm by it to express it
    in reference-plane pixels.

    Parameters
    ----------
    texels_xy : (..., 2) float
        Points on z = 0, mm.

    Returns
    -------
    (...) float64; +inf where the point is behind the camera.
    """
    xy = np.asarray(texels_xy, dtype=np.float64)
    flat = xy.reshape(-1, 2)
    h = 1e-3
    pts = np.zeros((3, len(flat), 3))
    pts[:, :, :2] = flat
    pts[1, :, 0] += h
    pts[2, :, 1] += h
    pix, front = camera.project(pts.reshape(-1, 3))
    pix = pix.reshape(3, -1, 2)
    front = front.reshape(3, -1).all(axis=0)
    ju, jv = (pix[1] - pix[0]) / h, (pix[2] - pix[0]) / h
    det = np.abs(ju[:, 0] * jv[:, 1] - ju[:, 1] * jv[:, 0])
    ok = front & (det > 0)
    out = np.where(ok, 1.0 / np.sqrt(np.where(ok, det, 1.0)), np.inf)
    return out.reshape(xy.shape[:-1])


def displacement_image(
    peaks: PixelPeaks,
    planes: ScanPlanes,
    camera: PinholeCamera,
    texels_xy,
    *,
    weight: float,
    max_error_gain: float = 10.0,
    edge_tol_px: float = 2.0,
    above_tol_px: float = 0.5,
) -> ScanDisplacement:
    """Triangulate a scan's peaks on the texel grid.

    Parameters
    ----------
    peaks : PixelPeaks
        Space-time peaks of the scan, (H, W) matching ``camera``.
    planes : ScanPlanes
        Laser plane of every frame of the scan.
    camera : PinholeCamera
        Sample frame, mm.
    texels_xy : (N, M, 2) float
        Reference points, e.g. ``rig.geometry.texel_centers_mm``.
    weight : float
        Stored in the result for the merge.
    max_error_gain : float
        Largest accepted 1/|n·d| (ray/plane sine below 1/gain is GRAZING).
    edge_tol_px : float
        Largest spread of the neighbours' D blended together, in
        reference-plane pixels.
    above_tol_px : float
        Points higher than this above z = 0 are ABOVE_REFERENCE; between 0
        and this they are clamped to distance 0.

    Returns
    -------
    ScanDisplacement
    """
    xy = np.asarray(texels_xy, dtype=np.float64)
    if xy.ndim != 3 or xy.shape[-1] != 2:
        raise MdfError(f"texels_xy must be (N, M, 2) mm, got shape {xy.shape}")
    h, w = peaks.time.shape
    if (w, h) != (camera.width, camera.height):
        raise MdfError(f"peaks are {h}×{w} pixels but the camera is {camera.height}×{camera.width}")
    if len(planes.offset) != peaks.frames:
        raise MdfError(f"{len(planes.offset)} planes for a scan of {peaks.frames} frames")
    if not max_error_gain > 1:
        raise MdfError(f"max_error_gain must exceed 1, got {max_error_gain}")
    grid_shape = xy.shape[:2]
    flat = xy.reshape(-1, 2)
    q = np.column_stack([flat, np.zeros(len(flat))])
    pix, front = camera.project(q)
    u, v = pix[:, 0], pix[:, 1]
    inside = front & (u >= 0) & (u <= w - 1) & (v >= 0) & (v <= h - 1)
    x0 = np.clip(np.floor(u), 0, max(w - 2, 0)).astype(np.intp)
    y0 = np.clip(np.floor(v), 0, max(h - 2, 0)).astype(np.intp)
    fx, fy = np.clip(u - x0, 0, 1), np.clip(v - y0, 0, 1)
    xs = np.stack([x0, np.minimum(x0 + 1, w - 1), x0, np.minimum(x0 + 1, w - 1)])
    ys = np.stack([y0, y0, np.minimum(y0 + 1, h - 1), np.minimum(y0 + 1, h - 1)])
    wts = np.stack([(1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy])

    center = camera.center
    ray = q - center
    direction = ray / np.linalg.norm(ray, axis=1)[:, None]
    footprint = reference_footprint_mm(camera, flat)
    _, pixel_dirs = camera.rays(np.column_stack([xs.ravel(), ys.ravel()]))
    pixel_dirs = pixel_dirs.reshape(4, -1, 3)

    time = peaks.time[ys, xs].astype(np.float64)  # (4, n)
    reason = peaks.reason[ys, xs].copy()
    normal, offset, plane_ok = planes.at(time)
    denom = np.einsum("kni,kni->kn", normal, pixel_dirs)
    grazing = np.abs(denom) * max_error_gain < 1.0
    safe = np.where(grazing | ~plane_ok, 1.0, denom)
    points = center + ((offset - normal @ center) / safe)[..., None] * pixel_dirs
    # Each neighbour's surface point, as a distance along the texel's ray.
    dist = np.einsum("kni,ni->kn", points - q, direction)
    above = dist < -above_tol_px * footprint
    ok = reason == Reason.OK
    reason[ok & ~plane_ok] = Reason.NO_PLANE
    reason[ok & plane_ok & grazing] = Reason.GRAZING
    reason[ok & plane_ok & ~grazing & above] = Reason.ABOVE_REFERENCE
    good = reason == Reason.OK
    dist = np.where(good, np.maximum(dist, 0.0), 0.0)

    w_good = np.where(good, wts, 0.0)
    w_sum = w_good.sum(axis=0)
    blended = (w_good * dist).sum(axis=0) / np.where(w_sum > 0, w_sum, 1.0)
    spread = np.where(good, dist, -np.inf).max(axis=0) - np.where(good, dist, np.inf).min(axis=0)
    nearest = np.argmax(w_good, axis=0)
    cols = np.arange(len(flat))
    edge = spread > edge_tol_px * footprint
    value = np.where(edge, dist[nearest, cols], blended)
    # Texels without enough valid neighbours take the reason of the nearest
    # invalid one.
    worst = np.argmax(np.where(good, -1.0, wts), axis=0)
    out_reason = np.where(edge, Reason.EDGE, Reason.OK).astype(np.uint8)
    out_reason = np.where(w_sum >= 0.5, out_reason, reason[worst, cols])
    out_reason[~inside] = Reason.OUTSIDE_IMAGE
    valid = out_reason <= Reason.EDGE
    distance = np.where(valid, value, -1.0).astype(np.float32)
    return ScanDisplacement(
        distance=distance.reshape(grid_shape),
        reason=out_reason.reshape(grid_shape),
        weight=float(weight),
    )
