"""An image file's size from its header, before anything is decoded.

A file whose header claims more pixels than a reader can hold is refused from
those few bytes, instead of by a decoder's assertion or an out-of-memory error
half-way through: PNG (IHDR), JPEG (the SOF segment), TIFF (the first IFD),
Radiance HDR (the resolution line) and OpenEXR (the data window).
"""

from __future__ import annotations

import re
import struct
from pathlib import Path
from typing import BinaryIO

from rig.interchange._errors import InterchangeError

__all__ = ["MAX_IMAGE_PIXELS", "check_image_size", "image_size"]

#: the most pixels an image read whole may have (8192 × 8192): a float32 RGBA
#: frame of it is 1 GiB
MAX_IMAGE_PIXELS = 8192 * 8192
#: how much of a file's start is read to tell its format (and a Radiance HDR's size)
_HEAD_BYTES = 4096
_PNG = b"\x89PNG\r\n\x1a\n"
_JPEG_SOF = {0xC0, 0xC1, 0xC2, 0xC3, 0xC5, 0xC6, 0xC7, 0xC9, 0xCA, 0xCB, 0xCD, 0xCE, 0xCF}
_HDR_RESOLUTION = re.compile(rb"\n([-+])([XY]) (\d+) ([-+])([XY]) (\d+)\n")


def image_size(path) -> tuple[int, int]:
    """``(width, height)`` in pixels as the header of ``path`` says (nothing decoded).

    Raises InterchangeError naming the file when its header cannot be read.
    """
    path = Path(path)
    if path.suffix.lower() == ".exr":
        return _exr_size(path)
    try:
        with path.open("rb") as f:
            head = f.read(_HEAD_BYTES)
            size = None
            if head.startswith(_PNG) and head[12:16] == b"IHDR":
                size = struct.unpack(">II", head[16:24])
            elif head.startswith(b"\xff\xd8"):
                size = _jpeg_size(f)
            elif head[:4] in (b"II*\x00", b"MM\x00*"):
                size = _tiff_size(f, "<" if head[:2] == b"II" else ">")
            elif head.startswith((b"#?RADIANCE", b"#?RGBE")):
                match = _HDR_RESOLUTION.search(head)
                if match is not None:
                    first, second = int(match[3]), int(match[6])
                    size = (second, first) if match[2] == b"Y" else (first, second)
    except OSError as err:
        raise InterchangeError(f"{path}: cannot be read ({err.strerror})") from err
    except struct.error:  # a header cut short
        size = None
    if size is None:
        raise InterchangeError(
            f"{path}: unreadable: no PNG, JPEG, TIFF or Radiance HDR header gives its size "
            "(a damaged file, or another format)"
        )
    return int(size[0]), int(size[1])


def check_image_size(path, *, max_pixels: int = MAX_IMAGE_PIXELS) -> tuple[int, int]:
    """``(width, height)`` of ``path``; InterchangeError naming the file and the size
    when the image has no pixels or more than ``max_pixels``."""
    width, height = image_size(path)
    if not 0 < width * height <= max_pixels:
        raise InterchangeError(
            f"{path}: {width}×{height} pixels; images of 1 to {max_pixels} pixels are read "
            f"(e.g. 8192×8192); scale it down first"
        )
    return width, height


def _jpeg_size(f: BinaryIO) -> tuple[int, int] | None:
    """From the first SOF segment, walking the segments before it (EXIF, ICC…) by
    their lengths."""
    f.seek(2)
    while True:
        marker = f.read(2)
        if len(marker) < 2 or marker[0] != 0xFF:
            return None
        if marker[1] == 0xFF:  # a fill byte
            f.seek(-1, 1)
            continue
        if marker[1] == 0x01 or 0xD0 <= marker[1] <= 0xD9:  # markers without a length
            continue
        (length,) = struct.unpack(">H", f.read(2))
        if length < 2:  # a damaged segment would never advance
            return None
        if marker[1] in _JPEG_SOF:
            _, height, width = struct.unpack(">BHH", f.read(5))
            return width, height
        f.seek(length - 2, 1)


def _tiff_size(f: BinaryIO, order: str) -> tuple[int, int] | None:
    """ImageWidth and ImageLength of the first IFD (libtiff writes it after the pixels)."""
    f.seek(4)
    (ifd,) = struct.unpack(order + "I", f.read(4))
    f.seek(ifd)
    (count,) = struct.unpack(order + "H", f.read(2))
    entries = f.read(12 * count)
    tags: dict[int, int] = {}
    for at in range(0, len(entries) - 11, 12):
        tag, kind = struct.unpack_from(order + "HH", entries, at)
        if tag in (256, 257) and kind in (3, 4):  # ImageWidth, ImageLength: SHORT or LONG
            tags[tag] = struct.unpack_from(order + ("H" if kind == 3 else "I"), entries, at + 8)[0]
    if 256 not in tags or 257 not in tags:
        return None
    return tags[256], tags[257]


def _exr_size(path: Path) -> tuple[int, int]:
    import OpenEXR

    try:
        with OpenEXR.File(str(path), header_only=True) as exr:
            low, high = exr.header()["dataWindow"]
    except Exception as err:  # the bindings raise bare exceptions
        raise InterchangeError(f"{path}: not a readable OpenEXR image ({err})") from err
    return int(high[0]) - int(low[0]) + 1, int(high[1]) - int(low[1]) + 1
