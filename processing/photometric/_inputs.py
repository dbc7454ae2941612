"""Validation of image stacks and masks at the photometric API boundary."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._errors import PhotometricError

ACCEPTED_DTYPES = (np.uint8, np.uint16, np.float32, np.float64)


@dataclass(frozen=True)
class Stack:
    """An image stack flattened to (L, N) or (L, N, C), with how to read its values.

    ``gain`` (L, C) maps a stored value to normalised intensity per unit lamp
    colour (1/dtype max for integers, 1 for floats, divided by the lamps'
    colour balance when they have per-channel intensities); ``clip_raw``
    (L, C) is the stored value at or above which an observation is clipped
    (inf when none) — compared before any division, as a sensor clips.
    """

    values: np.ndarray
    shape: tuple[int, int]
    channels: int
    scale: float
    gain: np.ndarray
    clip_raw: np.ndarray

    @property
    def clips(self) -> bool:
        """Whether any observation can count as clipped."""
        return bool(np.isfinite(self.clip_raw).any())


def check_stack(
    images, n_lights: int, saturation_level, colour_balance: np.ndarray | None = None
) -> Stack:
    """Validate ``images`` against the lights and flatten it (no copy if contiguous).

    ``saturation_level`` is None, one normalised level, one per light (L,) or
    one per light and channel (L, C); ``colour_balance`` (L, 3) comes from
    lamps with per-channel intensities and needs colour images.
    """
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
    if colour_balance is not None and channels == 1:
        raise PhotometricError(
            "lights: per-channel intensities (L, 3) need colour images (L, H, W, 3), got grey "
            "images; give (L,) intensities for grey images"
        )
    flat = images.reshape(n_lights, h * w) if channels == 1 else images.reshape(n_lights, h * w, 3)
    integer = np.issubdtype(images.dtype, np.integer)
    scale = 1.0 / np.iinfo(images.dtype).max if integer else 1.0
    saturation = _saturation(saturation_level, n_lights, channels, 1.0 if integer else np.inf)
    gain = np.full((n_lights, channels), scale)
    if colour_balance is not None:
        gain = gain / colour_balance
    return Stack(flat, (h, w), channels, scale, gain, saturation / scale)


def _saturation(level, n_lights: int, channels: int, default: float) -> np.ndarray:
    """(L, C) normalised clipping levels from None, a number, (L,) or (L, C)."""
    if level is None:
        return np.full((n_lights, channels), default)
    expected = f"a normalised level > 0 (1.0 = integer full scale), one per light ({n_lights},)"
    if channels > 1:
        expected += f" or one per light and channel ({n_lights}, {channels})"
    try:
        arr = np.array(level, dtype=np.float64)
    except (TypeError, ValueError) as err:
        raise PhotometricError(f"saturation_level: expected {expected}, got {level!r}") from err
    if arr.shape not in ((), (n_lights,), (n_lights, channels)):
        raise PhotometricError(f"saturation_level: expected {expected}, got shape {arr.shape}")
    if np.any(np.isnan(arr) | (arr <= 0)):
        raise PhotometricError(f"saturation_level: expected {expected}, got {level!r}")
    if arr.ndim == 1:
        arr = arr[:, None]
    return np.broadcast_to(arr, (n_lights, channels)).copy()


def check_mask(mask, shape: tuple[int, int]) -> np.ndarray | None:
    """(H·W,) bool of ``mask`` or None when every pixel is wanted.

    Bool arrays, and bool-like integer masks as image files hold them (0 and
    1, or 0 and the dtype's maximum, e.g. 0/255 in uint8), are accepted.
    """
    if mask is None:
        return None
    arr = np.asarray(mask)
    integer = np.issubdtype(arr.dtype, np.integer)
    if arr.shape != shape or not (integer or arr.dtype == np.bool_):
        raise PhotometricError(
            f"mask: expected a bool array (or an integer 0/1 or 0/255 mask) of shape {shape}, "
            f"got {arr.dtype} {arr.shape}"
        )
    if integer:
        values = np.unique(arr).tolist()
        top = int(np.iinfo(arr.dtype).max)
        if not (set(values) <= {0, 1} or set(values) <= {0, top}):
            shown = ", ".join(str(v) for v in values[:5]) + (" …" if len(values) > 5 else "")
            raise PhotometricError(
                f"mask: an integer mask must hold only 0 and one 'on' value (1 or {top}); "
                f"got values {shown}"
            )
        arr = arr != 0
    return None if arr.all() else arr.reshape(-1)


def check_positive(value: float, name: str, *, allow_zero: bool = False) -> float:
    """A finite float > 0 (or ≥ 0), else a PhotometricError naming ``name``."""
    ok = np.isfinite(value) and (value >= 0 if allow_zero else value > 0)
    if not ok:
        bound = "≥ 0" if allow_zero else "> 0"
        raise PhotometricError(f"{name}: expected a finite number {bound}, got {value!r}")
    return float(value)
