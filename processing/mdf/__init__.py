"""MDF reconstruction from laser scans (seed ``001_…`` section 3, Wang et al. 2005).

Per frame (the live worker's part): find the laser line in the reference
region around the sample and the laser plane it implies. Per scan (one view,
one laser location): the space-time peak of every pixel, triangulated against
the plane of its peak time, read along each texel's view ray → D_{v,l}. Per
view: merge over laser locations with the seed's tetrahedron weights → D_v.
All lengths in mm, sample frame; -1 marks unseen texels, reason codes say why.
"""

from processing.mdf._errors import MdfError
from processing.mdf._reason import Reason, reason_counts
from processing.mdf.displacement import ScanDisplacement, displacement_image, reference_footprint_mm
from processing.mdf.line import LaserLine, LineReason, detect_laser_line, frame_intensity
from processing.mdf.merge import (
    Mdf,
    ViewDisplacement,
    assemble_mdf,
    merge_scans,
    view_direction_deg,
)
from processing.mdf.peaks import PEAK_METHODS, PeakMethod, peak_offset, peak_radius
from processing.mdf.reference import ReferenceRegion, plate_points, profile_axis_for
from processing.mdf.scan import MdfSettings, ScanAccumulator, frame_laser_line, reconstruct_scan
from processing.mdf.sheet import ScanPlanes, scan_planes, sheet_from_line, tetrahedron_weight
from processing.mdf.spacetime import PixelPeaks, SpaceTimeTracker, space_time_peaks

__all__ = [
    "PEAK_METHODS",
    "LaserLine",
    "LineReason",
    "Mdf",
    "MdfError",
    "MdfSettings",
    "PeakMethod",
    "PixelPeaks",
    "Reason",
    "ReferenceRegion",
    "ScanAccumulator",
    "ScanDisplacement",
    "ScanPlanes",
    "SpaceTimeTracker",
    "ViewDisplacement",
    "assemble_mdf",
    "detect_laser_line",
    "displacement_image",
    "frame_intensity",
    "frame_laser_line",
    "merge_scans",
    "peak_offset",
    "peak_radius",
    "plate_points",
    "profile_axis_for",
    "reason_counts",
    "reconstruct_scan",
    "reference_footprint_mm",
    "scan_planes",
    "sheet_from_line",
    "space_time_peaks",
    "tetrahedron_weight",
    "view_direction_deg",
]
