"""Laser-plane angle to the reference plane from strips on planes of known height.

Seed 001 §3.2: project the laser strip onto two planes at different heights;
the strip moves sideways by Δ between them, and the plane's angle α to the
reference plane follows from the height offset h: tan α = h / Δ. With more
than two heights the offsets are fitted by a line (offset = c − h·cot α) whose
residual says how planar the sheet and how good the measurements are.

References
----------
.. [1] Wang et al., "Capturing and rendering geometry details for BTF-mapped
   surfaces", The Visual Computer 21 (2005), §3.2.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from processing.mdf import frame_intensity, peak_offset
from rig.camera import PinholeCamera
from rig.errors import RigError
from rig.targets import LaserStepTarget

__all__ = [
    "LaserAngle",
    "LaserCalibrationError",
    "band_offsets",
    "laser_plane_angle",
    "strip_offset_mm",
    "strip_pixels",
]


class LaserCalibrationError(RigError):
    """The laser calibration input cannot give a trustworthy angle."""


@dataclass(frozen=True)
class LaserAngle:
    """The fitted angle of a laser sheet to the reference plane.

    ``angle_deg`` in (0, 180): below 90° the sheet leans so that the strip
    moves towards −u as the height grows (u is the across-strip axis the
    offsets were measured along). ``residual_mm`` is the RMS misfit of the
    offsets (0 with exactly two heights); ``angle_std_deg`` a 1-σ uncertainty
    from the residual and, with two heights, from ``offset_std_mm``.
    """

    angle_deg: float
    residual_mm: float
    angle_std_deg: float
    heights: int


def strip_offset_mm(points_mm, direction) -> np.ndarray:
    """Signed distance of strip points across the strip direction.

    Parameters
    ----------
    points_mm : (n, 2) float
        Points of one detected strip on the reference plane, mm.
    direction : (2,) float
        The strip's direction; the across axis is ``direction`` turned +90°.

    Returns
    -------
    float64 scalar
        The mean across-strip coordinate of the points (the strip's offset).
    """
    p = np.asarray(points_mm, dtype=np.float64).reshape(-1, 2)
    d = np.asarray(direction, dtype=np.float64)
    norm = np.linalg.norm(d)
    if len(p) == 0 or not np.isfinite(norm) or norm == 0:
        raise LaserCalibrationError("strip_offset_mm: need ≥ 1 point and a non-zero direction")
    across = np.array([-d[1], d[0]]) / norm
    return np.float64(np.mean(p @ across))


def laser_plane_angle(
    heights_mm, offsets_mm, *, offset_std_mm: float = 0.05, min_height_span_mm: float = 1.0
) -> LaserAngle:
    """Angle of a laser sheet to the reference plane from strip offsets.

    Parameters
    ----------
    heights_mm : (k,) float
        Heights of the target planes above the reference plane, k ≥ 2.
    offsets_mm : (k,) float
        Across-strip offset of the strip on each plane (``strip_offset_mm``).
    offset_std_mm : float
        Measurement noise of one offset, for the uncertainty estimate.
    min_height_span_mm : float
        Heights closer than this cannot resolve the angle (seed: "two heights
        that are nearly equal") and raise ``LaserCalibrationError``.

    Examples
    --------
    >>> round(laser_plane_angle([0.0, 10.0], [0.0, -10.0]).angle_deg, 6)
    45.0
    """
    h = np.asarray(heights_mm, dtype=np.float64).ravel()
    u = np.asarray(offsets_mm, dtype=np.float64).ravel()
    if h.shape != u.shape or len(h) < 2:
        raise LaserCalibrationError(
            f"need the same number (≥ 2) of heights and offsets, got {len(h)} and {len(u)}"
        )
    if not (np.all(np.isfinite(h)) and np.all(np.isfinite(u))):
        raise LaserCalibrationError("heights and offsets must be finite")
    span = np.ptp(h)
    if span < min_height_span_mm:
        raise LaserCalibrationError(
            f"the target heights span {span:.3f} mm; at least {min_height_span_mm} mm is "
            "needed to resolve the angle — use a higher second plane"
        )
    # offset = c + s·h with s = −cot α; least squares in float64.
    A = np.column_stack([np.ones_like(h), h])
    coef, *_ = np.linalg.lstsq(A, u, rcond=None)
    slope = coef[1]
    fit = A @ coef
    dof = len(h) - 2
    residual = float(np.sqrt(np.mean((u - fit) ** 2))) if dof > 0 else 0.0
    angle = float(np.rad2deg(np.arctan2(1.0, -slope)))
    sigma = residual * np.sqrt(len(h) / dof) if dof > 0 else offset_std_mm * np.sqrt(2)
    slope_std = sigma / np.sqrt(np.sum((h - h.mean()) ** 2))
    # dα/ds = −1/(1+s²) in radians
    angle_std = float(np.rad2deg(slope_std / (1.0 + slope * slope)))
    return LaserAngle(angle, residual, angle_std, len(h))


def strip_pixels(frame, *, profile_axis: int, threshold: float = 0.3) -> np.ndarray:
    """(n, 2) sub-pixel (x, y) of the laser strip in a laser-only frame.

    Each image line across the strip (columns for ``profile_axis`` 0, rows for
    1) contributes its brightest sample, when above ``threshold`` × the frame's
    peak, refined by a Gaussian fit to it and its neighbours.
    """
    img = frame_intensity(frame).astype(np.float64)
    if profile_axis == 1:
        img = img.T
    peak = float(img.max())
    if not peak > 0:
        raise LaserCalibrationError("the laser frame is dark: no strip to find")
    rows = np.argmax(img, axis=0)
    cols = np.arange(img.shape[1])
    inside = (rows >= 1) & (rows < img.shape[0] - 1) & (img[rows, cols] > threshold * peak)
    rows, cols = rows[inside], cols[inside]
    window = np.stack([img[rows - 1, cols], img[rows, cols], img[rows + 1, cols]])
    offset, ok = peak_offset(window, method="gaussian")
    along, across = cols[ok].astype(np.float64), rows[ok] + offset[ok]
    xy = np.column_stack([along, across]) if profile_axis == 0 else np.column_stack([across, along])
    return xy


def band_offsets(
    pixels,
    camera: PinholeCamera,
    steps: LaserStepTarget,
    *,
    sample_mm: float,
    margin_mm: float = 3.0,
    min_points: int = 10,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Strip offsets on each band of the step target, from strip pixels.

    Each pixel's ray meets band *i*'s plane z = h_i; the point counts for band
    *i* when it lies inside that band (``margin_mm`` clear of its edges, where
    the walls are). The strip's direction is fitted to all points together,
    and each band's offset is its points' mean across that direction.

    Returns ``(heights_mm, offsets_mm, direction)`` of the bands that hold at
    least ``min_points`` points.
    """
    origin, dirs = camera.rays(np.asarray(pixels, dtype=np.float64).reshape(-1, 2))
    edges = steps.band_edges_mm(sample_mm)
    heights, groups = [], []
    for h, y0, y1 in zip(steps.heights_mm, edges[:-1], edges[1:], strict=True):
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (h - origin[2]) / dirs[:, 2]
        points = origin[None, :] + t[:, None] * dirs
        keep = np.isfinite(t) & (t > 0) & (points[:, 1] > y0 + margin_mm)
        keep &= (points[:, 1] < y1 - margin_mm) & (np.abs(points[:, 0]) < sample_mm / 2)
        if keep.sum() >= min_points:
            heights.append(h)
            groups.append(points[keep, :2])
    if len(groups) < 2:
        raise LaserCalibrationError(
            f"the strip crosses {len(groups)} band(s) of the step target with ≥ {min_points} "
            "points each; at least 2 are needed (is the strip across the bands and in view?)"
        )
    centred = np.vstack([g - g.mean(axis=0) for g in groups])
    _, _, vt = np.linalg.svd(centred, full_matrices=False)
    direction = vt[0] if vt[0][1] >= 0 else -vt[0]
    offsets = np.array([strip_offset_mm(g, direction) for g in groups])
    return np.array(heights), offsets, direction
