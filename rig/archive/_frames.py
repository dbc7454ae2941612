"""One camera's frame array: chunk files written and read without zarr's I/O loop.

Each frame is one chunk of the Zarr v3 array ``frames/<camera>``: its pixels,
little-endian and C-ordered (the ``bytes`` codec), compressed by zstd with the
content checksum on (the ``zstd`` codec, via numcodecs, as zarr itself does).
Writing chunk files directly lets the archive order and ``fsync`` them before
a commit, and compress them in its own thread pool (zstd releases the GIL).

Each chunk file ends with the frame's own record (step, camera, sub, exposure,
timestamp, position, and how many frames each camera has in the step) in a
zstd *skippable frame*, which every zstd decoder, zarr's included, passes
over. The journal is the authority; these records let ``rig repair`` rebuild
a lost journal from the chunks.

References
----------
.. [1] Zstandard compression format, RFC 8878, section 3.1.2 (skippable frames).
"""

from __future__ import annotations

import json
import os
import re
import struct
import zlib
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
from numcodecs import Zstd

from rig.archive._errors import ArchiveError
from rig.archive._records import FrameFormat
from rig.archive._store import chunk_name

__all__ = ["ChunkScan", "FrameArray", "chunk_record"]

_CHUNK_RE = re.compile(r"c\.(\d+)\.0\.0\.0")
#: A zstd skippable frame (magic 0x184D2A50–5F, then the length of its content).
_SKIPPABLE = struct.Struct("<II")
_SKIPPABLE_MAGIC = 0x184D2A5B
#: The record's content ends with (CRC-32 of the JSON, its length, a tag).
_TAIL = struct.Struct("<II4s")
_TAG = b"BTFR"


def chunk_record(record: dict[str, Any]) -> bytes:
    """The skippable zstd frame that carries a frame's ``record`` (plain JSON values)."""
    body = json.dumps(record, sort_keys=True, separators=(",", ":"), allow_nan=False).encode()
    content = body + _TAIL.pack(zlib.crc32(body), len(body), _TAG)
    return _SKIPPABLE.pack(_SKIPPABLE_MAGIC, len(content)) + content


class ChunkScan(NamedTuple):
    """What ``FrameArray.scan_chunks`` found, by frame position."""

    #: Size in bytes of each chunk file (a regular file).
    sizes: dict[int, int]
    #: What sits under a chunk's name but is not a regular file ("a directory", …).
    strays: dict[int, str]


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

    def write(self, position: int, image: np.ndarray, record: bytes, *, fsync: bool) -> int:
        """Compress ``image`` (already checked) into chunk ``position``, followed by
        its ``record`` (from :func:`chunk_record`); bytes written."""
        path = self.path(position)
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | os.O_NOFOLLOW, 0o644)
        try:
            for part in (self._codec.encode(image), record):
                data = memoryview(part)
                while data:
                    data = data[os.write(fd, data) :]
            if fsync:
                os.fsync(fd)
            return os.fstat(fd).st_size
        except OSError as err:
            raise OSError(err.errno, err.strerror, str(path)) from err  # name the file
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

    def scan_chunks(self) -> ChunkScan:
        """The chunk files present, and what else sits under a chunk's name.

        Only regular files are chunks; links are never followed (a link could
        lead into another archive).
        """
        scan = ChunkScan({}, {})
        with os.scandir(self.directory) as entries:
            for entry in entries:
                match = _CHUNK_RE.fullmatch(entry.name)
                if match is None:
                    continue
                position = int(match.group(1))
                if entry.is_file(follow_symlinks=False):
                    scan.sizes[position] = entry.stat(follow_symlinks=False).st_size
                elif entry.is_symlink():
                    scan.strays[position] = "a symbolic link"
                elif entry.is_dir(follow_symlinks=False):
                    scan.strays[position] = "a directory"
                else:
                    scan.strays[position] = "a special file"
        return scan

    def read_record(self, position: int) -> dict[str, Any] | None:
        """The record at the end of chunk ``position``; None when there is none whole.

        A record is trusted only when its CRC matches and it names this
        camera and position (a chunk cut short by a crash has none).
        """
        try:
            with open(self.path(position), "rb") as f:
                size = f.seek(0, os.SEEK_END)
                if size < _SKIPPABLE.size + _TAIL.size:
                    return None
                f.seek(size - _TAIL.size)
                crc, length, tag = _TAIL.unpack(f.read(_TAIL.size))
                start = size - _TAIL.size - length - _SKIPPABLE.size
                if tag != _TAG or start < 0:
                    return None
                f.seek(start)
                magic, content_length = _SKIPPABLE.unpack(f.read(_SKIPPABLE.size))
                body = f.read(length)
        except FileNotFoundError:
            return None
        if (magic, content_length) != (_SKIPPABLE_MAGIC, length + _TAIL.size):
            return None
        if zlib.crc32(body) != crc:
            return None
        try:
            record = json.loads(body)
        except ValueError:
            return None
        if not isinstance(record, dict):
            return None
        if record.get("camera") != self.camera or record.get("position") != position:
            return None
        return record
