"""Checks shared by the camera drivers: settings in range, frames as the spec says."""

from __future__ import annotations

import numpy as np

from drivers.camera._interface import CameraSettings
from drivers.errors import DeviceError, ProtocolError
from rig.config import CameraSpec

__all__ = [
    "BIT_DEPTHS",
    "MAX_EXPOSURE_S",
    "MAX_GAIN",
    "check_image",
    "dtype_for",
    "expected_shape",
    "updated_settings",
]

BIT_DEPTHS = (8, 10, 12, 16)
MAX_EXPOSURE_S = 60.0
MAX_GAIN = 64.0


def dtype_for(bit_depth: int) -> np.dtype:
    """uint8 for 8-bit frames, uint16 for 10, 12 and 16 bits."""
    return np.dtype(np.uint8 if bit_depth == 8 else np.uint16)


def expected_shape(spec: CameraSpec) -> tuple[int, ...]:
    """(height, width) for mono, (height, width, 3) for colour."""
    return (spec.height, spec.width) if spec.channels == 1 else (spec.height, spec.width, 3)


def updated_settings(
    device: str,
    current: CameraSettings,
    *,
    exposure_s: float | None,
    gain: float | None,
    bit_depth: int | None,
    bit_depths: tuple[int, ...] = BIT_DEPTHS,
) -> CameraSettings:
    """``current`` with the given values replaced, each checked; ``DeviceError`` names the field."""
    if exposure_s is not None and not 0 < exposure_s <= MAX_EXPOSURE_S:
        raise DeviceError(
            device, "configure", f"exposure_s={exposure_s} is outside (0, {MAX_EXPOSURE_S}] s"
        )
    if gain is not None and not 0 < gain <= MAX_GAIN:
        raise DeviceError(
            device, "configure", f"gain={gain} is outside (0, {MAX_GAIN}] (linear, 1 = unity)"
        )
    if bit_depth is not None and bit_depth not in bit_depths:
        raise DeviceError(
            device, "configure", f"bit_depth={bit_depth} is not supported; valid are {bit_depths}"
        )
    return CameraSettings(
        exposure_s=current.exposure_s if exposure_s is None else float(exposure_s),
        gain=current.gain if gain is None else float(gain),
        bit_depth=current.bit_depth if bit_depth is None else int(bit_depth),
    )


def check_image(device: str, image: np.ndarray, spec: CameraSpec, bit_depth: int) -> None:
    """``ProtocolError`` (worth a re-capture) when a frame's shape, dtype or range is wrong."""
    shape = expected_shape(spec)
    if image.shape != shape:
        raise ProtocolError(
            device, "capture", f"frame has shape {image.shape}, the camera's spec says {shape}"
        )
    dtype = dtype_for(bit_depth)
    if image.dtype != dtype:
        raise ProtocolError(
            device, "capture", f"frame has dtype {image.dtype}, expected {dtype} at {bit_depth} bit"
        )
    if bit_depth not in (8, 16):
        top = int(image.max(initial=0))
        if top >= 1 << bit_depth:
            raise ProtocolError(device, "capture", f"frame has value {top}, beyond {bit_depth} bit")
