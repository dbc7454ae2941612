"""Calibration of the rig: cameras (ChArUco), lamps (mirror sphere, diffuse
target), laser planes (two or more heights) and the radiometric response."""

from calibration.cameras import (
    CameraCalibration,
    CameraCalibrationError,
    CharucoView,
    TurntableAxis,
    calibrate_intrinsics,
    detect_charuco,
    turntable_axis,
)
from calibration.lamps import (
    FlatField,
    Highlight,
    LampCalibrationError,
    LampPosition,
    find_highlight,
    flat_fields,
    reflected_ray,
    sphere_center_from_silhouette,
    triangulate_lamp,
)
from calibration.laser import LaserAngle, LaserCalibrationError, laser_plane_angle, strip_offset_mm
from calibration.response import (
    Radiance,
    ResponseCurve,
    ResponseError,
    calibrate_response,
    merge_bracket,
)

__all__ = [
    "CameraCalibration",
    "CameraCalibrationError",
    "CharucoView",
    "FlatField",
    "Highlight",
    "LampCalibrationError",
    "LampPosition",
    "LaserAngle",
    "LaserCalibrationError",
    "Radiance",
    "ResponseCurve",
    "ResponseError",
    "TurntableAxis",
    "calibrate_intrinsics",
    "calibrate_response",
    "detect_charuco",
    "find_highlight",
    "flat_fields",
    "laser_plane_angle",
    "merge_bracket",
    "reflected_ray",
    "sphere_center_from_silhouette",
    "strip_offset_mm",
    "triangulate_lamp",
    "turntable_axis",
]
