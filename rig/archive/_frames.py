"""One camera's frame array: chunk files written and read without zarr's I/O loop.

Each frame is one chunk of the Zarr v3 array ``frames/<camera>``: its pixels,
little-endian and C-ordered (the ``bytes`` codec), compressed by zstd with the
content checksum on (the ``zstd`` codec, via numcodecs, as zarr itself does).
Writing chunk files directly lets the archive order and ``fsync`` them before
a commit, and compress them in its own thread pool (zstd releases the GIL).
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np
from numcodecs import Zstd

from rig.archive._errors import ArchiveError
from rig.archive._records import FrameFormat
from rig.archive._store import chunk_name

__all__ = ["FrameArray"]

_CHUNK_RE = re.compile(r"c\.(\d+)\.0\.0\.0")


class FrameArray:
    """Chunk files of ``frames/<camera>`` in ``directory``."""

    def __init__(self, directory: Path, camera: str, frame_format: FrameFormat, zstd_level: int):
        self.directory = directory
        self.camera = camera
        self.format = frame_format
        self._codec = Zstd(level=zstd_level, checksum=True)
        self._dtype = np.dtype(frame_format.dtype).newbyteorder("<")

    def path(self, position: int) -> Path:
        """Path of the chunk file of frame ``position``."""
        return self.directory / chunk_name(position)

    def check_image(self, image, *, where: str) -> np.ndarray:
        """``image`` as a C-contiguous little-endian ``(H, W, C)`` array, or ArchiveError."""
        if not isinstance(image, np.ndarray):
            raise ArchiveError(f"{where}: expected a numpy array, got {type(image).__name__}")
        fmt = self.format
        if image.ndim == 2 and fmt.channels == 1:
            image = image[:, :, np.newaxis]
        if image.shape != fmt.shape or image.dtype.name != fmt.dtype:
            raise ArchiveError(
                f"{where}: got a {image.dtype.name} frame of shape {image.shape}, camera "
                f"{self.camera!r} delivers {fmt.dtype} frames of shape {fmt.shape}"
            )
        # No copy when the frame is already contiguous and little-endian (the usual case).
        return np.ascontiguousarray(image, dtype=self._dtype)

    def write(self, position: int, image: np.ndarray, *, fsync: bool) -> int:
        """Compress ``image`` (already checked) into chunk ``position``; bytes written."""
        data = memoryview(self._codec.encode(image))
        fd = os.open(self.path(position), os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
        try:
            while data:
                data = data[os.write(fd, data) :]
            if fsync:
                os.fsync(fd)
            return os.fstat(fd).st_size
        finally:
            os.close(fd)

    def read(self, position: int, *, nbytes: int, where: str) -> np.ndarray:
        """Decode chunk ``position`` into a ``(H, W, C)`` array of the camera's dtype.

        ``nbytes`` is the chunk size recorded at commit; a missing, truncated
        or corrupt chunk raises ArchiveError naming ``where`` and the file.
        """
        path = self.path(position)
        try:
            data = path.read_bytes()
        except FileNotFoundError as err:
            raise ArchiveError(f"{where}: chunk file {path} is missing") from err
        if len(data) != nbytes:
            raise ArchiveError(
                f"{where}: chunk file {path} has {len(data)} bytes, {nbytes} were committed "
                "(truncated or overwritten)"
            )
        try:
            raw = self._codec.decode(data)
        except (RuntimeError, ValueError) as err:
            raise ArchiveError(f"{where}: chunk file {path} is corrupt: {err}") from err
        if len(raw) != self.format.nbytes:
            raise ArchiveError(
                f"{where}: chunk file {path} decodes to {len(raw)} bytes, a "
                f"{self.format.dtype} frame of shape {self.format.shape} has "
                f"{self.format.nbytes}"
            )
        image = np.frombuffer(raw, dtype=self._dtype).reshape(self.format.shape)
        return image.astype(self.format.dtype, copy=False)

    def chunk_sizes(self) -> dict[int, int]:
        """Size in bytes of every chunk file present, by frame position."""
        sizes = {}
        with os.scandir(self.directory) as entries:
            for entry in entries:
                match = _CHUNK_RE.fullmatch(entry.name)
                if match:
                    sizes[int(match.group(1))] = entry.stat().st_size
        return sizes

    def remove(self, positions) -> None:
        """Delete the chunk files of ``positions`` (uncommitted leftovers)."""
        for position in positions:
            self.path(position).unlink(missing_ok=True)
