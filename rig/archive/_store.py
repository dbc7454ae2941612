"""Zarr v3 metadata documents and crash-safe small-file writes.

The archive writes its ``zarr.json`` documents itself (they follow the Zarr v3
core specification, and any zarr reader opens them) so that no write goes
through zarr's global event-loop thread and every write is ordered and
``fsync``-ed as the commit protocol needs.

References
----------
.. [1] Zarr core specification, version 3.0,
   https://zarr-specs.readthedocs.io/en/latest/v3/core/index.html
"""

from __future__ import annotations

import json
import os
import re
from pathlib import Path
from typing import Any

from rig.archive._errors import ArchiveDamaged, ArchiveError
from rig.archive._records import FrameFormat

__all__ = [
    "array_document",
    "check_array_document",
    "check_inside",
    "check_name",
    "chunk_name",
    "fsync_dir",
    "group_document",
    "hidden_node_document",
    "overlaps_archive",
    "read_document",
    "write_atomic",
]

#: Frames of one camera are chunked one image per chunk; "." keeps every
#: chunk of an array in one directory (one file per frame, no sub-folders).
_CHUNK_SEPARATOR = "."
#: What a name that becomes a path component inside the archive may look like
#: (a camera, a material result): no "/", no "..", nothing hidden.
_NAME_RE = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_\-]{0,63}")


def check_name(name: Any, *, what: str) -> str:
    """``name`` if it is safe as one path component inside the archive, else ArchiveError.

    ``what`` says where the name comes from (``"camera name"``, an attribute…);
    the message names it and the bad value.
    """
    if not isinstance(name, str) or not _NAME_RE.fullmatch(name):
        raise ArchiveError(
            f"{what} {name!r}: use 1–64 letters, digits, '_' and '-', not starting with '-'"
        )
    return name


def check_inside(root: Path, relative: str) -> Path:
    """``root / relative``, or ArchiveDamaged when a symbolic link on the way leads elsewhere.

    An archive's folders and files are its own, never links: a link could lead
    into another archive, whose files recovery would then move or rewrite. A
    path that does not exist yet passes (what is missing is named elsewhere).
    """
    path = root / relative
    real = os.path.realpath(path)
    if real != os.path.join(os.path.realpath(root), relative):
        raise ArchiveDamaged(
            f"{path}: a symbolic link (it leads to {real}); an archive's folders and files "
            "are its own, never links: the archive is damaged or was crafted, and nothing "
            "in it was touched"
        )
    return path


def overlaps_archive(path: str | os.PathLike, archive: str | os.PathLike) -> bool:
    """Whether ``path`` is the archive, lies inside it or holds it (links resolved).

    Writing there would change the archive (or delete it, when replacing ``path``).
    """
    resolved, source = Path(path).resolve(), Path(archive).resolve()
    return resolved == source or source in resolved.parents or resolved in source.parents


def chunk_name(position: int) -> str:
    """File name of the chunk holding frame ``position`` of a camera array."""
    return f"c.{position}.0.0.0"


def fsync_dir(path: Path) -> None:
    """Make the entries of directory ``path`` (new or renamed files) durable."""
    fd = os.open(path, os.O_RDONLY | os.O_DIRECTORY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def write_atomic(path: Path, data: bytes, *, fsync: bool) -> None:
    """Replace ``path`` by ``data`` so that a reader sees the old or the new file.

    Writes a temporary sibling, optionally ``fsync``-s it, then ``os.replace``-s
    it over ``path`` (atomic on POSIX) and ``fsync``-s the directory.
    """
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.unlink(missing_ok=True)  # left by a crash; "x" never follows a planted link
    try:
        with open(tmp, "xb") as f:
            f.write(data)
            if fsync:
                f.flush()
                os.fsync(f.fileno())
    except OSError:
        tmp.unlink(missing_ok=True)  # our own half-written copy (a full disk)
        raise
    os.replace(tmp, path)
    if fsync:
        fsync_dir(path.parent)


def _dumps(document: dict) -> bytes:
    return json.dumps(document, indent=2, allow_nan=False).encode()


def group_document(attributes: dict[str, Any] | None = None) -> bytes:
    """``zarr.json`` of a Zarr v3 group."""
    return _dumps({"zarr_format": 3, "node_type": "group", "attributes": attributes or {}})


def array_document(frame_format: FrameFormat, *, length: int, zstd_level: int) -> bytes:
    """``zarr.json`` of one camera's frame array, shape ``(length, H, W, C)``.

    One frame per chunk, codecs ``bytes`` (little-endian) then ``zstd`` with
    its content checksum, so that a corrupted chunk fails to decode.
    """
    bytes_codec: dict[str, Any] = {"name": "bytes"}
    if frame_format.dtype != "uint8":
        bytes_codec["configuration"] = {"endian": "little"}
    fill_value = 0.0 if frame_format.dtype == "float32" else 0
    return _dumps(
        {
            "zarr_format": 3,
            "node_type": "array",
            "shape": [length, *frame_format.shape],
            "data_type": frame_format.dtype,
            "chunk_grid": {
                "name": "regular",
                "configuration": {"chunk_shape": [1, *frame_format.shape]},
            },
            "chunk_key_encoding": {
                "name": "default",
                "configuration": {"separator": _CHUNK_SEPARATOR},
            },
            "fill_value": fill_value,
            "codecs": [
                bytes_codec,
                {"name": "zstd", "configuration": {"level": zstd_level, "checksum": True}},
            ],
            "dimension_names": ["frame", "y", "x", "channel"],
            "attributes": {},
        }
    )


def hidden_node_document(description: str) -> bytes:
    """``zarr.json`` of an empty array node (``log``, ``quarantine``) that holds plain files.

    zarr never lists inside an array, so its readers see no stray files.
    """
    return _dumps(
        {
            "zarr_format": 3,
            "node_type": "array",
            "shape": [0],
            "data_type": "uint8",
            "chunk_grid": {"name": "regular", "configuration": {"chunk_shape": [1]}},
            "chunk_key_encoding": {"name": "default", "configuration": {"separator": "/"}},
            "fill_value": 0,
            "codecs": [{"name": "bytes"}],
            "attributes": {"description": description},
        }
    )


def read_document(path: Path, *, node_type: str) -> dict[str, Any]:
    """Parse the ``zarr.json`` at ``path`` and check it is a v3 ``node_type``."""
    try:
        document = json.loads(path.read_bytes())
    except FileNotFoundError as err:
        raise ArchiveError(f"{path.parent}: missing {node_type} metadata {path.name}") from err
    except (OSError, ValueError) as err:
        raise ArchiveError(f"{path}: unreadable metadata: {err}") from err
    if not isinstance(document, dict):
        raise ArchiveError(f"{path}: metadata is not a JSON object")
    if document.get("zarr_format") != 3 or document.get("node_type") != node_type:
        raise ArchiveError(
            f"{path}: expected a Zarr v3 {node_type}, found zarr_format="
            f"{document.get('zarr_format')!r} node_type={document.get('node_type')!r}"
        )
    return document


def check_array_document(path: Path, document: dict, frame_format: FrameFormat) -> tuple[int, int]:
    """Check a camera array against its ``FrameFormat``.

    Returns
    -------
    length, zstd_level : int
        Frames the array's shape declares, and its zstd level.
    """
    dtype = document.get("data_type")
    if dtype != frame_format.dtype:
        raise ArchiveError(
            f"{path}: dtype {dtype!r}, but the archive declares {frame_format.dtype!r} "
            "for this camera"
        )
    shape = document.get("shape")
    if not isinstance(shape, list) or len(shape) != 4 or list(shape[1:]) != [*frame_format.shape]:
        raise ArchiveError(
            f"{path}: shape {shape!r}, expected [n, {', '.join(map(str, frame_format.shape))}]"
        )
    chunk_shape = document.get("chunk_grid", {}).get("configuration", {}).get("chunk_shape")
    separator = document.get("chunk_key_encoding", {}).get("configuration", {}).get("separator")
    if chunk_shape != [1, *frame_format.shape] or separator != _CHUNK_SEPARATOR:
        raise ArchiveError(
            f"{path}: chunking {chunk_shape!r} with separator {separator!r}; the archive "
            f"stores one frame per chunk, [1, {', '.join(map(str, frame_format.shape))}] "
            f"with separator {_CHUNK_SEPARATOR!r}"
        )
    codecs = document.get("codecs")
    names = [c.get("name") for c in codecs] if isinstance(codecs, list) else codecs
    if names != ["bytes", "zstd"]:
        raise ArchiveError(f"{path}: codecs {names!r}, expected ['bytes', 'zstd']")
    return int(shape[0]), int(codecs[1].get("configuration", {}).get("level", 3))
