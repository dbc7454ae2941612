"""One laser scan, frame by frame: the live worker's part and its finish.

A scan is one (view, laser location) image sequence with the turntable at rest.
:class:`ScanAccumulator` takes frames one at a time — for each it finds the
laser line in the reference region (returned, so a live worker can report it)
and feeds the space-time tracker — and :meth:`ScanAccumulator.finish` turns the
lot into the displacement image D_{v,l} on the texel grid.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from processing.mdf._errors import MdfError
from processing.mdf.displacement import ScanDisplacement, displacement_image
from processing.mdf.line import LaserLine, detect_laser_line
from processing.mdf.peaks import PeakMethod, peak_radius
from processing.mdf.reference import ReferenceRegion, profile_axis_for
from processing.mdf.sheet import ScanPlanes, scan_planes, tetrahedron_weight
from processing.mdf.spacetime import SpaceTimeTracker

__all__ = ["MdfSettings", "ScanAccumulator", "frame_laser_line", "reconstruct_scan"]


@dataclass(frozen=True)
class MdfSettings:
    """The knobs of the MDF reconstruction (intensities in frame units; the
    defaults suit 8-bit frames — scale them for deeper ones).

    Attributes
    ----------
    peak_method : {"centroid", "gaussian", "blais_rioux"}
        Sub-pixel detector for the line and the space-time peak.
    line_threshold : float
        Minimum pre-filtered intensity of a line candidate.
    min_contrast : float
        Minimum rise of a pixel above its darkest frame to count as lit.
    sigma_px : float
        Gaussian pre-filter of the line detection.
    inlier_tol_px, min_inliers, min_span_mm, ransac_iterations
        Robust line fit (:func:`~processing.mdf.line.detect_laser_line`).
    max_error_gain, edge_tol_px, above_tol_px
        Triangulation guards (:func:`~processing.mdf.displacement.displacement_image`).
    """

    peak_method: PeakMethod = "gaussian"
    line_threshold: float = 40.0
    min_contrast: float = 20.0
    sigma_px: float = 1.0
    inlier_tol_px: float = 1.0
    min_inliers: int = 8
    min_span_mm: float = 20.0
    ransac_iterations: int = 64
    max_error_gain: float = 10.0
    edge_tol_px: float = 2.0
    above_tol_px: float = 0.5

    def __post_init__(self) -> None:
        peak_radius(self.peak_method)  # validates the name
        for name in ("line_threshold", "min_contrast", "inlier_tol_px", "min_span_mm"):
            if not getattr(self, name) > 0:
                raise MdfError(f"MdfSettings.{name} must be > 0, got {getattr(self, name)}")
        if self.sigma_px < 0:
            raise MdfError(f"MdfSettings.sigma_px must be ≥ 0, got {self.sigma_px}")
        if self.min_inliers < 2 or self.ransac_iterations < 1:
            raise MdfError(
                "MdfSettings: min_inliers must be ≥ 2 and ransac_iterations ≥ 1, got "
                f"{self.min_inliers}, {self.ransac_iterations}"
            )


class ScanAccumulator:
    """Frame-by-frame processing of one scan.

    Parameters
    ----------
    region : ReferenceRegion
        Of the scanning camera (sample frame).
    source_mm : (3,) float
        Laser emitter position, sample frame, mm.
    settings : MdfSettings
    """

    def __init__(self, region: ReferenceRegion, *, source_mm, settings: MdfSettings):
        source = np.asarray(source_mm, dtype=np.float64)
        if source.shape != (3,) or not np.all(np.isfinite(source)) or source[2] <= 0:
            raise MdfError(f"source_mm must be a finite 3-vector above the plate, got {source_mm}")
        self.region = region
        self.source_mm = source
        self.settings = settings
        self.profile_axis = _profile_axis(region, source)
        self.lines: list[LaserLine] = []
        self._tracker = SpaceTimeTracker(
            region.mask.shape, method=settings.peak_method, min_contrast=settings.min_contrast
        )

    def add(self, frame) -> LaserLine:
        """Process the next frame; returns its laser line."""
        line = _line(frame, self.region, self.profile_axis, self.settings, seed=len(self.lines))
        self._tracker.update(frame)
        self.lines.append(line)
        return line

    def planes(self, *, sheet_angle_deg=None) -> ScanPlanes:
        """The laser planes of the frames so far (see :func:`scan_planes`)."""
        if not self.lines:
            raise MdfError("ScanAccumulator: no frame was added")
        return scan_planes(self.lines, source_mm=self.source_mm, angle_deg=sheet_angle_deg)

    def finish(self, texels_xy, *, sheet_angle_deg=None) -> ScanDisplacement:
        """D_{v,l} on the texel grid.

        Parameters
        ----------
        texels_xy : (N, N, 2) float
            ``rig.geometry.texel_centers_mm(sample_mm, N)``.
        sheet_angle_deg : None, float or (F,) float
            Angle of the laser plane to the reference plane from calibration
            (per frame if it varies over the sweep); None: planes through the
            emitter (:func:`~processing.mdf.sheet.sheet_from_line`).
        """
        planes = self.planes(sheet_angle_deg=sheet_angle_deg)
        peaks = self._tracker.result()
        xy = np.asarray(texels_xy, dtype=np.float64)
        weight = 0.0
        if planes.valid.any():
            n = planes.normal[planes.valid]
            strips = np.column_stack([n[:, 1], -n[:, 0]])  # N × z, horizontal
            strips *= np.sign(strips @ strips[0])[:, None]
            weight = tetrahedron_weight(
                self.source_mm,
                self.region.camera.center,
                strips.mean(axis=0),
                half_length_mm=float(np.abs(xy).max()),
            )
        s = self.settings
        return displacement_image(
            peaks,
            planes,
            self.region.camera,
            xy,
            weight=weight,
            max_error_gain=s.max_error_gain,
            edge_tol_px=s.edge_tol_px,
            above_tol_px=s.above_tol_px,
        )


def frame_laser_line(
    frame, region: ReferenceRegion, *, source_mm, settings: MdfSettings | None = None
) -> LaserLine:
    """The laser line of one frame on its own (the live worker's per-frame part)."""
    source = np.asarray(source_mm, dtype=np.float64)
    return _line(frame, region, _profile_axis(region, source), settings or MdfSettings(), seed=0)


def _profile_axis(region: ReferenceRegion, source: np.ndarray) -> int:
    # The strip runs across the emitter's azimuth; search across it.
    strip = np.array([-source[1], source[0]])
    return profile_axis_for(region.camera, strip if strip.any() else [1.0, 0])


def _line(frame, region, profile_axis: int, s: MdfSettings, *, seed: int) -> LaserLine:
    return detect_laser_line(
        frame,
        region,
        profile_axis=profile_axis,
        threshold=s.line_threshold,
        sigma_px=s.sigma_px,
        method=s.peak_method,
        inlier_tol_px=s.inlier_tol_px,
        min_inliers=s.min_inliers,
        min_span_mm=s.min_span_mm,
        ransac_iterations=s.ransac_iterations,
        seed=seed,
    )


def reconstruct_scan(
    frames: Iterable,
    region: ReferenceRegion,
    texels_xy,
    *,
    source_mm,
    sheet_angle_deg=None,
    settings: MdfSettings | None = None,
) -> ScanDisplacement:
    """D_{v,l} of one scan from its frames (streamed, e.g. from an archive).

    Parameters
    ----------
    frames : iterable of (H, W) or (H, W, C) arrays
    region : ReferenceRegion
    texels_xy : (N, N, 2) float
    source_mm : (3,) float
    sheet_angle_deg : None, float or (F,) float
    settings : MdfSettings, default ``MdfSettings()``

    Returns
    -------
    ScanDisplacement
    """
    acc = ScanAccumulator(region, source_mm=source_mm, settings=settings or MdfSettings())
    for frame in frames:
        acc.add(frame)
    return acc.finish(texels_xy, sheet_angle_deg=sheet_angle_deg)
