"""Laser line detection in the reference region of one frame.

Seed ``001_…`` section 3.2, "Initial displacement images": Gaussian-filter the
image, search the reference region along the laser scan direction for the
brightest candidate per profile (above a prescribed threshold), and fit a line
to the candidates. Here the candidates are refined to sub-pixel precision,
back-projected onto the reference plane z = 0 (so lens distortion is undone and
the line is fitted in millimetres), and the fit is robust: RANSAC on pairs of
candidates, then a total-least-squares refit on the inliers, so a glint or a
specular hot spot on the plate is rejected rather than averaged in.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum

import cv2
import numpy as np

from processing.mdf._errors import MdfError
from processing.mdf.peaks import PeakMethod, peak_offset, peak_radius
from processing.mdf.reference import ReferenceRegion, plate_points

__all__ = ["LaserLine", "LineReason", "detect_laser_line", "frame_intensity"]


class LineReason(IntEnum):
    """Why a frame has (or has no) laser line."""

    OK = 0
    #: Fewer than ``min_inliers`` candidates above the threshold: no line in
    #: the reference region (laser off, strip outside the plate).
    NO_CANDIDATES = 1
    #: Candidates exist but no line gathers ``min_inliers`` of them.
    NO_CONSENSUS = 2
    #: The inliers span less than ``min_span_mm`` along the line.
    SHORT = 3


@dataclass(frozen=True)
class LaserLine:
    """The laser strip on the reference plane z = 0 for one frame.

    The line is ``normal · (x, y) = rho_mm`` in the sample frame. When
    ``reason`` is not OK, ``normal`` is (0, 0) and ``rho_mm`` is 0.

    Attributes
    ----------
    normal : (2,) float64 unit vector (or zeros)
    rho_mm : float
    candidates : int
        Profiles with a candidate above the threshold.
    inliers : int
        Candidates within ``inlier_tol_px`` of the final line.
    rms_mm : float
        RMS distance of the inliers from the line.
    span_mm : float
        Extent of the inliers along the line.
    reason : LineReason
    """

    normal: np.ndarray
    rho_mm: float
    candidates: int
    inliers: int
    rms_mm: float
    span_mm: float
    reason: LineReason

    @property
    def valid(self) -> bool:
        return self.reason == LineReason.OK


def frame_intensity(frame) -> np.ndarray:
    """(H, W) float32 intensity of a (H, W) or (H, W, C) frame.

    Colour frames are reduced by the maximum over channels: the laser is
    monochromatic, so its own channel carries the signal.
    """
    f = np.asarray(frame)
    if f.ndim == 3:
        f = f.max(axis=2)
    if f.ndim != 2:
        raise MdfError(f"frame must be (H, W) or (H, W, C), got shape {np.shape(frame)}")
    return np.ascontiguousarray(f, dtype=np.float32)


def detect_laser_line(
    frame,
    region: ReferenceRegion,
    *,
    profile_axis: int,
    threshold: float,
    sigma_px: float = 1.0,
    method: PeakMethod = "gaussian",
    inlier_tol_px: float = 1.0,
    min_inliers: int = 8,
    min_span_mm: float = 20.0,
    ransac_iterations: int = 64,
    seed: int = 0,
) -> LaserLine:
    """Find the laser strip in the reference region of one frame.

    Parameters
    ----------
    frame : (H, W) or (H, W, C) array
        One laser scan image, any numeric dtype.
    region : ReferenceRegion
        Of the camera that took ``frame``.
    profile_axis : {0, 1}
        0: one candidate per column (searched down the column); 1: one per
        row. See :func:`~processing.mdf.reference.profile_axis_for`.
    threshold : float
        Minimum filtered intensity of a candidate, in the frame's units.
    sigma_px : float
        Gaussian pre-filter (0 disables it).
    method : {"centroid", "gaussian", "blais_rioux"}
        Sub-pixel detector across the strip.
    inlier_tol_px : float
        RANSAC inlier distance, in pixels (converted with the region's
        footprint).
    min_inliers, min_span_mm : int, float
        A line needs this many inliers spanning this far along it.
    ransac_iterations, seed : int
        Candidate pairs tried, from a generator seeded with ``seed``.

    Returns
    -------
    LaserLine
    """
    intensity = frame_intensity(frame)
    if intensity.shape != region.mask.shape:
        raise MdfError(
            f"frame shape {intensity.shape} does not match the reference region "
            f"{region.mask.shape} of this camera"
        )
    if profile_axis not in (0, 1):
        raise MdfError(f"profile_axis must be 0 (columns) or 1 (rows), got {profile_axis}")
    if sigma_px > 0:
        intensity = cv2.GaussianBlur(intensity, (0, 0), sigma_px, borderType=cv2.BORDER_REFLECT)
    r = peak_radius(method)
    # A candidate's whole window must lie in the region, and so must what the
    # pre-filter mixed into it (the recess and the floor beyond the plate).
    blur = int(np.ceil(2.5 * sigma_px))
    shape = (2 * (r + blur) + 1, 2 * blur + 1)  # (rows, cols) of the kernel
    kernel = np.ones(shape if profile_axis == 0 else shape[::-1], np.uint8)
    centres = cv2.erode(region.mask.astype(np.uint8), kernel, borderType=cv2.BORDER_CONSTANT)
    masked = np.where(centres > 0, intensity, -np.inf).astype(np.float32)
    best = cv2.reduceArgMax(masked, profile_axis).ravel().astype(np.intp)
    lines = np.arange(best.size)  # the profile index: a column (axis 0) or a row
    peak = masked[best, lines] if profile_axis == 0 else masked[lines, best]
    keep = np.flatnonzero(peak >= threshold)
    if keep.size < min_inliers:
        return _no_line(LineReason.NO_CANDIDATES, keep.size)
    along = best[keep]
    steps = np.arange(-r, r + 1)[:, None]
    if profile_axis == 0:
        window = intensity[along[None, :] + steps, keep[None, :]]
    else:
        window = intensity[keep[None, :], along[None, :] + steps]
    # A maximum pressed against the region's edge is a slope, not the strip.
    local_max = (window[r] >= window[r - 1]) & (window[r] >= window[r + 1])
    # Background: the region's median (a 3-sample window has no room for its own).
    background = np.median(intensity[region.mask][::7])
    offset, ok = peak_offset(window - background, method=method)
    ok &= local_max
    pos = along[ok] + offset[ok]
    across = keep[ok].astype(np.float64)
    pixels = np.column_stack([across, pos] if profile_axis == 0 else [pos, across])
    points, front = plate_points(region.camera, pixels)
    points = points[front]
    if len(points) < min_inliers:
        return _no_line(LineReason.NO_CANDIDATES, len(points))
    tol_mm = inlier_tol_px * region.footprint_mm
    return _fit_line(
        points,
        tol_mm=tol_mm,
        min_inliers=min_inliers,
        min_span_mm=min_span_mm,
        iterations=ransac_iterations,
        rng=np.random.default_rng(seed),
    )


def _no_line(reason: LineReason, candidates: int) -> LaserLine:
    return LaserLine(np.zeros(2), 0.0, int(candidates), 0, 0.0, 0.0, reason)


def _tls(points: np.ndarray) -> tuple[np.ndarray, float]:
    centre = points.mean(axis=0)
    _, _, vt = np.linalg.svd(points - centre, full_matrices=False)
    normal = vt[-1]
    return normal, float(normal @ centre)


def _fit_line(points, *, tol_mm, min_inliers, min_span_mm, iterations, rng) -> LaserLine:
    n = len(points)
    pairs = rng.integers(0, n, size=(iterations, 2))
    a, b = points[pairs[:, 0]], points[pairs[:, 1]]
    d = b - a
    length = np.hypot(d[:, 0], d[:, 1])
    usable = length > tol_mm
    normals = np.column_stack([-d[:, 1], d[:, 0]]) / np.where(usable, length, 1.0)[:, None]
    rho = np.einsum("ij,ij->i", normals, a)
    dist = np.abs(points @ normals.T - rho)  # (n, iterations)
    votes = np.where(usable, (dist <= tol_mm).sum(axis=0), 0)
    best = int(np.argmax(votes))
    if votes[best] < min_inliers:
        return _no_line(LineReason.NO_CONSENSUS, n)
    inl = dist[:, best] <= tol_mm
    # Two TLS refits: the first moves the line off the sampled pair's noise.
    for _ in range(2):
        normal, rho_fit = _tls(points[inl])
        inl = np.abs(points @ normal - rho_fit) <= tol_mm
        if inl.sum() < min_inliers:
            return _no_line(LineReason.NO_CONSENSUS, n)
    normal, rho_fit = _tls(points[inl])
    resid = points[inl] @ normal - rho_fit
    along = points[inl] @ np.array([-normal[1], normal[0]])
    span = float(along.max() - along.min())
    reason = LineReason.OK if span >= min_span_mm else LineReason.SHORT
    if reason != LineReason.OK:
        return LaserLine(np.zeros(2), 0.0, n, int(inl.sum()), 0.0, span, reason)
    return LaserLine(
        normal=normal,
        rho_mm=rho_fit,
        candidates=n,
        inliers=int(inl.sum()),
        rms_mm=float(np.sqrt(np.mean(resid**2))),
        span_mm=span,
        reason=reason,
    )
