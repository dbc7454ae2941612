"""Registration of BTF frames: holder markers → homography → normtexture.

Seed ``000_…`` §3.2: every frame is projected onto the reference plane through
markers on the sample holder plate and resampled on the shared texel grid
(``rig.geometry.texel_centers_mm``). The marker layout and corner convention
are documented in ``docs/btf.md``.
"""

from processing.registration._capture import CaptureRegistration, register_capture
from processing.registration._errors import Reason, RegistrationError
from processing.registration._homography import (
    PlaneHomography,
    distort_px,
    fit_plane_homography,
    pose_plane_homography,
    undistort_px,
)
from processing.registration._markers import (
    MarkerDetection,
    aruco_dictionary,
    detect_markers,
    marker_corners_mm,
)
from processing.registration._predicted import expected_corners_px, track_markers
from processing.registration._rectify import (
    AREA_SAMPLES_PER_PIXEL,
    FILTERS,
    Normtexture,
    Region,
    blend_edges,
    rectify,
    subgrid,
)
from processing.registration._register import Registration, register_frame

__all__ = [
    "AREA_SAMPLES_PER_PIXEL",
    "FILTERS",
    "CaptureRegistration",
    "MarkerDetection",
    "Normtexture",
    "PlaneHomography",
    "Reason",
    "Region",
    "Registration",
    "RegistrationError",
    "aruco_dictionary",
    "blend_edges",
    "detect_markers",
    "distort_px",
    "expected_corners_px",
    "fit_plane_homography",
    "marker_corners_mm",
    "pose_plane_homography",
    "rectify",
    "register_capture",
    "register_frame",
    "subgrid",
    "track_markers",
    "undistort_px",
]
