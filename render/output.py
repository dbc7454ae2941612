"""Writing rendered images: an sRGB 8-bit PNG with an exposure, or a float EXR.

The renderer's images are linear radiance. For display they are scaled by
2^exposure_ev, clipped to [0, 1] and encoded with the sRGB transfer curve
(IEC 61966-2-1); for compositing they are written unchanged as 32-bit float
OpenEXR. The sRGB curve and the OpenEXR writer are ``rig.interchange``'s,
shared with the exporters.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from render._errors import RenderError
from rig.interchange import InterchangeError, to_srgb
from rig.interchange import write_exr as write_float_image

__all__ = ["to_srgb8", "write_exr", "write_png"]


def _image(image) -> np.ndarray:
    a = np.asarray(image, dtype=np.float32)
    if a.ndim != 3 or a.shape[2] != 3 or 0 in a.shape:
        raise RenderError(f"image: expected (H, W, 3) linear RGB, got shape {a.shape}")
    return a


def to_srgb8(image, *, exposure_ev: float = 0.0) -> np.ndarray:
    """(H, W, 3) uint8 sRGB of a linear image scaled by 2^exposure_ev.

    NaN counts as black and values beyond 1 (after exposure) as white.
    """
    if not np.isfinite(exposure_ev):
        raise RenderError(f"exposure_ev = {exposure_ev}: must be a finite number of stops")
    return to_srgb(_image(image) * 2.0**exposure_ev)


def _folder(path: Path) -> None:
    if not path.parent.is_dir():
        raise RenderError(f"{path}: folder {path.parent} does not exist")


def write_png(path, image, *, exposure_ev: float = 0.0) -> Path:
    """Write ``image`` (linear RGB) as an 8-bit sRGB PNG; returns the path."""
    path = Path(path)
    if path.suffix.lower() != ".png":
        raise RenderError(f"{path}: a PNG needs the suffix .png")
    _folder(path)
    if not cv2.imwrite(
        str(path), np.ascontiguousarray(to_srgb8(image, exposure_ev=exposure_ev)[..., ::-1])
    ):
        raise RenderError(f"{path}: could not be written (is the folder writable?)")
    return path


def write_exr(path, image) -> Path:
    """Write ``image`` (linear RGB) unchanged as a 32-bit float OpenEXR; returns the path."""
    path = Path(path)
    if path.suffix.lower() != ".exr":
        raise RenderError(f"{path}: an OpenEXR image needs the suffix .exr")
    _folder(path)
    try:
        return write_float_image(path, _image(image))
    except InterchangeError as err:
        raise RenderError(str(err)) from err
