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

from rig.errors import RigError

__all__ = ["LaserAngle", "LaserCalibrationError", "laser_plane_angle", "strip_offset_mm"]


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
