"""Image files in and out: 8/16-bit PNG and TIFF (OpenCV), float OpenEXR (OpenEXR).

One place for the sRGB transfer curve (IEC 61966-2-1) and for OpenEXR, which
the renderer's output and the exporters share (OpenCV's wheels are built
without EXR). Arrays are RGB(A) or grey, ``(H, W, C)``; files on disk follow
each format's own channel order.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from rig.interchange._errors import InterchangeError, InterchangeWriteError
from rig.interchange._imagesize import check_image_size

__all__ = [
    "IMAGE_SUFFIXES",
    "read_image",
    "srgb_decode",
    "srgb_encode",
    "to_srgb",
    "write_exr",
    "write_image",
]

#: suffixes read_image reads and write_image writes
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".exr")
_CV2_DTYPES = ("uint8", "uint16")


def srgb_encode(linear) -> np.ndarray:
    """The sRGB encoding in [0, 1] of linear values (clipped to [0, 1]; NaN → 0)."""
    x = np.clip(np.nan_to_num(np.asarray(linear, np.float64), nan=0.0), 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


def srgb_decode(encoded) -> np.ndarray:
    """Linear values of sRGB-encoded values in [0, 1] (float64)."""
    e = np.asarray(encoded, np.float64)
    return np.where(e <= 0.04045, e / 12.92, np.power((e + 0.055) / 1.055, 2.4))


def to_srgb(linear, *, dtype: str = "uint8") -> np.ndarray:
    """Linear values as sRGB-encoded ``uint8`` or ``uint16`` integers (rounded)."""
    if dtype not in _CV2_DTYPES:
        raise InterchangeError(f"dtype = {dtype!r}: sRGB integers are one of {_CV2_DTYPES}")
    full = float(np.iinfo(dtype).max)
    return np.round(srgb_encode(linear) * full).astype(dtype)


def read_image(path) -> np.ndarray:
    """The pixels of an image file: ``(H, W, C)`` RGB(A) or grey, in the file's dtype
    (uint8, uint16, or float32 for OpenEXR, finite).

    Raises InterchangeError naming the file when it is not an image this reads,
    when its header claims more than ``MAX_IMAGE_PIXELS`` pixels (checked
    before decoding), or when an OpenEXR holds NaN or inf.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in IMAGE_SUFFIXES:
        raise InterchangeError(
            f"{path}: not an image file (suffix {path.suffix!r}); images are {IMAGE_SUFFIXES}"
        )
    check_image_size(path)
    if suffix == ".exr":
        return _read_exr(path)
    import cv2

    try:
        image = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    except cv2.error as err:  # a header that contradicts the data
        raise InterchangeError(f"{path}: unreadable ({err.err})") from err
    if image is None or image.dtype.name not in _CV2_DTYPES:
        what = "unreadable" if image is None else f"of pixel type {image.dtype.name}"
        raise InterchangeError(
            f"{path}: {what}; expected an 8- or 16-bit {suffix.lstrip('.').upper()} image"
        )
    if image.ndim == 2:
        return image[:, :, np.newaxis]
    order = [2, 1, 0, 3][: image.shape[2]] if image.shape[2] in (3, 4) else [0]
    return np.ascontiguousarray(image[:, :, order])


def write_image(path, image) -> Path:
    """Write ``(H, W, C)`` pixels (C = 1, 3 or 4) unchanged: uint8/uint16 as PNG or
    TIFF, float32 as OpenEXR, chosen by the suffix; returns the path.

    InterchangeError for pixels or a suffix it cannot write; InterchangeWriteError
    naming the file when writing fails (a full disk).
    """
    path = Path(path)
    pixels = _pixels(image, path)
    suffix = path.suffix.lower()
    if suffix == ".exr":
        return write_exr(path, pixels)
    if suffix not in (".png", ".tif", ".tiff") or pixels.dtype.name not in _CV2_DTYPES:
        raise InterchangeError(
            f"{path}: write uint8/uint16 pixels as .png/.tif and float32 as .exr "
            f"(got {pixels.dtype.name} for {path.suffix!r})"
        )
    import cv2

    order = [2, 1, 0, 3][: pixels.shape[2]] if pixels.shape[2] in (3, 4) else [0]
    bgr = np.ascontiguousarray(pixels[:, :, order])
    try:
        written = cv2.imwrite(str(path), bgr)
    except cv2.error as err:
        raise InterchangeWriteError(f"{path}: could not be written ({err.err})") from err
    if not written:  # OpenCV says no more than that
        raise InterchangeWriteError(
            f"{path}: could not be written (a full disk, or a folder that is not writable)"
        )
    return path


def write_exr(path, image) -> Path:
    """Write ``(H, W)`` or ``(H, W, C)`` values as a 32-bit float OpenEXR (channels
    Y, RGB or RGBA; ZIP compression); returns the path."""
    import OpenEXR

    path = Path(path)
    pixels = _pixels(image, path).astype(np.float32)
    if pixels.shape[2] not in (1, 3, 4):
        raise InterchangeError(f"{path}: OpenEXR channels Y, RGB or RGBA; got {pixels.shape[2]}")
    name = {1: "Y", 3: "RGB", 4: "RGBA"}[pixels.shape[2]]
    data = pixels[:, :, 0] if name == "Y" else pixels
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    try:
        with OpenEXR.File(header, {name: np.ascontiguousarray(data)}) as exr:
            exr.write(str(path))
    except Exception as err:  # the bindings raise bare exceptions; the pixels were checked
        raise InterchangeWriteError(f"{path}: could not be written as OpenEXR ({err})") from err
    return path


def _read_exr(path: Path) -> np.ndarray:
    import OpenEXR

    try:
        with OpenEXR.File(str(path)) as exr:
            channels = {name: np.array(c.pixels) for name, c in exr.channels().items()}
    except Exception as err:  # the bindings raise bare exceptions
        raise InterchangeError(f"{path}: not a readable OpenEXR image ({err})") from err
    for name in ("RGBA", "RGB", "Y"):
        if name in channels:
            data = channels[name]
            pixels = (data if data.ndim == 3 else data[:, :, np.newaxis]).astype(np.float32)
            bad = np.count_nonzero(~np.isfinite(pixels))
            if bad:
                raise InterchangeError(
                    f"{path}: {bad} of {pixels.size} values are NaN or inf; radiance is "
                    "finite (replace them, e.g. by 0 or the neighbours' value)"
                )
            return pixels
    raise InterchangeError(f"{path}: OpenEXR channels {sorted(channels)}; expected Y, RGB or RGBA")


def _pixels(image, path: Path) -> np.ndarray:
    pixels = np.asarray(image)
    if pixels.ndim == 2:
        pixels = pixels[:, :, np.newaxis]
    if pixels.ndim != 3 or 0 in pixels.shape or pixels.shape[2] not in (1, 3, 4):
        raise InterchangeError(
            f"{path}: pixels of shape {pixels.shape}; expected (H, W) or (H, W, C), C = 1, 3, 4"
        )
    if pixels.dtype.kind == "f" and not np.all(np.isfinite(pixels)):
        raise InterchangeError(f"{path}: pixels hold NaN or inf; only finite values are written")
    return pixels
