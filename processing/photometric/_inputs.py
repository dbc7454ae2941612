"""Validation of image stacks and masks at the photometric API boundary."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._errors import PhotometricError

ACCEPTED_DTYPES = (np.uint8, np.uint16, np.float32, np.float64)


@dataclass(frozen=True)
class Stack:
    """An image stack flattened to (L, N) or (L, N, C), with its intensity scale.

    ``scale`` maps stored values to normalised intensity (1/dtype max for
    integers, 1 for floats); ``saturation`` is the normalised level at or
    above which an observation is clipped (inf when none).
    """

    values: np.ndarray
    shape: tuple[int, int]
    channels: int
    scale: float
    saturation: float


def check_stack(images, n_lights: int, saturation_level: float | None) -> Stack:
    """Validate ``images`` against the number of lights and flatten it (no copy if contiguous)."""
    if not isinstance(images, np.ndarray):
        raise PhotometricError(
            f"images: expected a numpy array (L, H, W) or (L, H, W, 3), got {type(images).__name__}"
        )
    if images.dtype.type not in ACCEPTED_DTYPES:
        raise PhotometricError(
            f"images: dtype {images.dtype} is not supported; use uint8, uint16, float32 or float64"
        )
    if images.ndim not in (3, 4) or (images.ndim == 4 and images.shape[3] != 3):
        raise PhotometricError(
            f"images: expected shape (L, H, W) or (L, H, W, 3), got {images.shape}"
        )
    if images.shape[0] != n_lights:
        raise PhotometricError(
            f"images: {images.shape[0]} images but {n_lights} lights; give one image per light"
        )
    if 0 in images.shape[1:3]:
        raise PhotometricError(f"images: image size must be at least 1×1, got {images.shape[1:3]}")
    h, w = images.shape[1:3]
    channels = 1 if images.ndim == 3 else 3
    flat = images.reshape(n_lights, h * w) if channels == 1 else images.reshape(n_lights, h * w, 3)
    if np.issubdtype(images.dtype, np.integer):
        scale = 1.0 / np.iinfo(images.dtype).max
        default_saturation = 1.0
    else:
        scale = 1.0
        default_saturation = np.inf
    if saturation_level is None:
        saturation = default_saturation
    elif not saturation_level > 0:
        raise PhotometricError(
            f"saturation_level: expected a normalised level > 0 (1.0 = integer full scale) "
            f"or None, got {saturation_level}"
        )
    else:
        saturation = float(saturation_level)
    return Stack(flat, (h, w), channels, scale, saturation)


def check_mask(mask, shape: tuple[int, int]) -> np.ndarray | None:
    """(H·W,) bool view of ``mask`` or None when every pixel is wanted."""
    if mask is None:
        return None
    arr = np.asarray(mask)
    if arr.dtype != np.bool_ or arr.shape != shape:
        raise PhotometricError(
            f"mask: expected a bool array of shape {shape}, got {arr.dtype} {arr.shape}"
        )
    return None if arr.all() else arr.reshape(-1)


def check_positive(value: float, name: str, *, allow_zero: bool = False) -> float:
    """A finite float > 0 (or ≥ 0), else a PhotometricError naming ``name``."""
    ok = np.isfinite(value) and (value >= 0 if allow_zero else value > 0)
    if not ok:
        bound = "≥ 0" if allow_zero else "> 0"
        raise PhotometricError(f"{name}: expected a finite number {bound}, got {value!r}")
    return float(value)
