"""Cameras behind one synchronous interface: the sim camera server, OpenCV, GenICam.

``open_device("camera", config.camera(id), clock=...)`` returns the driver the
camera's connection ``kind`` names; every driver implements ``Camera`` (``configure``,
``capture`` → ``Frame``, ``close``). ``GenicamCamera`` needs the optional
``btfrig[genicam]`` extra and is imported on demand.
"""

from drivers.camera import _open  # noqa: F401  (registers the camera kinds)
from drivers.camera._checks import check_image, dtype_for, expected_shape
from drivers.camera._interface import Camera, CameraSettings, Frame
from drivers.camera._opencv import OpenCvCamera
from drivers.camera._sim import SimCamera

__all__ = [
    "Camera",
    "CameraSettings",
    "Frame",
    "OpenCvCamera",
    "SimCamera",
    "check_image",
    "dtype_for",
    "expected_shape",
]
