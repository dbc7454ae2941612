"""The archive's folders and metadata: writing a new one, checking one that exists.

Every name read from an archive that becomes a path (a camera name in the root
attributes) is checked against a safe pattern first: a name is data, never a
path component that could lead outside the archive. Every folder and file the
archive reads or writes is checked to be its own, not reached through a
symbolic link (``check_inside``), before anything is read.
"""

from __future__ import annotations

import errno
import fcntl
import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rig.archive._errors import ArchiveDamaged, ArchiveError
from rig.archive._frames import FrameArray
from rig.archive._records import FrameFormat, json_safe
from rig.archive._store import (
    array_document,
    check_array_document,
    check_inside,
    check_name,
    group_document,
    hidden_node_document,
    read_document,
)
from rig.archive._versions import software_versions

__all__ = [
    "FORMAT_VERSION",
    "JOURNAL",
    "READABLE_VERSIONS",
    "Layout",
    "lock_writer",
    "read_layout",
    "root_attributes",
    "write_layout",
]

#: Version of the archive layout written by this code.
FORMAT_VERSION = 2
#: Versions this code reads: format 1 has no frame flags in its step records
#: (read as none); format 2 adds them (``StepRecord.flags``).
READABLE_VERSIONS = (1, 2)
# The journal and the writer lock sit inside the ``log`` node, an empty zarr
# array: zarr never lists inside an array, so zarr readers see no stray files.
JOURNAL = "log/journal.jsonl"
_LOCK = "log/writer.lock"
_LOG_DESCRIPTION = (
    "no data: the archive's append-only event log is the JSON-lines file "
    "log/journal.jsonl (see btfrig docs/archive.md)"
)
#: What an archive holds besides its camera folders, each checked to be its own.
_OWN = (
    "zarr.json",
    "frames",
    "frames/zarr.json",
    "calibration",
    "calibration/zarr.json",
    "material",
    "material/zarr.json",
    "log",
    "log/zarr.json",
    JOURNAL,
    _LOCK,
    "quarantine",
    "quarantine/zarr.json",
)
_ATTRIBUTES = ("btfrig_archive", "cameras", "zstd_level", "plan", "rig_config", "software")


@dataclass(frozen=True)
class Layout:
    """What an archive's metadata declares, checked against its folders."""

    attributes: dict[str, Any]
    cameras: dict[str, FrameFormat]
    arrays: dict[str, FrameArray]
    #: Frames each camera array's shape declares (a capacity, not a commit).
    capacity: dict[str, int]


def root_attributes(
    path: Path,
    *,
    plan: Mapping[str, Any],
    plan_toml: str | None,
    rig_config: Mapping[str, Any],
    cameras: Mapping[str, FrameFormat],
    zstd_level: int,
) -> dict[str, Any]:
    """The checked root attributes of a new archive at ``path``; ArchiveError names a bad one."""
    if not cameras:
        raise ArchiveError(f"{path}: cameras is empty; give at least one FrameFormat")
    for name, fmt in cameras.items():
        if not isinstance(fmt, FrameFormat):
            raise ArchiveError(f"{path}: cameras[{name!r}] is not a FrameFormat: {fmt!r}")
        check_name(name, what=f"{path}: camera name")
    if not (isinstance(zstd_level, int) and -7 <= zstd_level <= 22):
        raise ArchiveError(f"{path}: zstd_level = {zstd_level!r}, expected an int in -7..22")
    return {
        "btfrig_archive": {"format_version": FORMAT_VERSION},
        "cameras": {name: fmt.to_json() for name, fmt in cameras.items()},
        "zstd_level": zstd_level,
        "plan": json_safe(dict(plan), where="plan"),
        "plan_toml": plan_toml,
        "rig_config": json_safe(dict(rig_config), where="rig_config"),
        "software": software_versions(),
    }


def write_layout(
    directory: Path, attributes: dict[str, Any], cameras: Mapping[str, FrameFormat]
) -> None:
    """Write the folders and metadata of an empty archive into new ``directory``."""
    directory.mkdir(parents=True)
    (directory / "frames").mkdir()
    for name, fmt in cameras.items():
        (directory / "frames" / name).mkdir()
        doc = array_document(fmt, length=0, zstd_level=attributes["zstd_level"])
        (directory / "frames" / name / "zarr.json").write_bytes(doc)
    (directory / "frames" / "zarr.json").write_bytes(group_document())
    (directory / "calibration").mkdir()
    (directory / "calibration" / "zarr.json").write_bytes(
        group_document({"version": 0, "calibration": {}})
    )
    (directory / "material").mkdir()
    (directory / "material" / "zarr.json").write_bytes(group_document())
    (directory / "log").mkdir()
    (directory / "log" / "zarr.json").write_bytes(hidden_node_document(_LOG_DESCRIPTION))
    (directory / JOURNAL).touch()
    (directory / "zarr.json").write_bytes(group_document(attributes))


def read_layout(path: Path) -> Layout:
    """Check the metadata of the archive at ``path``; ArchiveError naming what is wrong."""
    for relative in _OWN:
        check_inside(path, relative)
    quarantine = path / "quarantine"
    if quarantine.exists() and not quarantine.is_dir():
        raise ArchiveDamaged(
            f"{quarantine}: not a folder; an archive's quarantine/ is the folder where recovery "
            "sets aside what it does not trust: move that file away"
        )
    root = read_document(path / "zarr.json", node_type="group")
    attributes = root.get("attributes")
    if not isinstance(attributes, dict):
        raise ArchiveDamaged(f"{path}/zarr.json: attributes = {attributes!r}, expected an object")
    for key in _ATTRIBUTES:
        if key not in attributes:
            raise ArchiveError(f"{path}/zarr.json: attribute {key!r} is missing")
    marker = attributes["btfrig_archive"]
    version = marker.get("format_version") if isinstance(marker, dict) else None
    if version not in READABLE_VERSIONS:
        raise ArchiveError(
            f"{path}: archive format version {version!r}, this btfrig reads "
            f"versions {list(READABLE_VERSIONS)}"
        )
    level = attributes["zstd_level"]
    if not isinstance(level, int) or isinstance(level, bool):
        raise ArchiveDamaged(f"{path}/zarr.json: attribute zstd_level = {level!r}, expected an int")
    for group in ("frames", "calibration", "material"):
        read_document(path / group / "zarr.json", node_type="group")
    read_document(path / "log" / "zarr.json", node_type="array")
    cameras = _read_cameras(path, attributes["cameras"])
    arrays, capacity = {}, {}
    for name, fmt in cameras.items():
        directory = check_inside(path, f"frames/{name}")
        check_inside(path, f"frames/{name}/zarr.json")
        document = read_document(directory / "zarr.json", node_type="array")
        capacity[name], level = check_array_document(directory / "zarr.json", document, fmt)
        arrays[name] = FrameArray(directory, name, fmt, level)
    return Layout(attributes, cameras, arrays, capacity)


def _read_cameras(path: Path, attribute: Any) -> dict[str, FrameFormat]:
    """The root attribute ``cameras``, checked: its names become folders under frames/."""
    where = f"{path / 'zarr.json'}: attribute cameras"
    if not isinstance(attribute, dict) or not attribute:
        raise ArchiveDamaged(f"{where} = {attribute!r}: expected {{name: frame format}}, ≥ 1")
    cameras = {}
    for name, fmt in attribute.items():
        try:
            check_name(name, what=f"{where}: camera name")
        except ArchiveError as err:
            raise ArchiveDamaged(f"{err}; the archive is damaged or was crafted") from err
        try:
            cameras[name] = FrameFormat.from_json(fmt)
        except (ArchiveError, KeyError, TypeError) as err:
            raise ArchiveDamaged(f"{where}[{name!r}] = {fmt!r}: {err}") from err
    return cameras


def lock_writer(path: Path) -> int:
    """Take the archive's writer lock; the descriptor to close to release it."""
    check_inside(path, "log")
    try:
        fd = os.open(path / _LOCK, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW, 0o644)
    except FileNotFoundError as err:
        raise ArchiveError(
            f"{path}: missing folder log/ (journal and writer lock); "
            "not a btfrig archive, or a damaged one"
        ) from err
    except OSError as err:
        if err.errno != errno.ELOOP:
            raise
        raise ArchiveDamaged(
            f"{path / _LOCK}: a symbolic link; an archive's files are its own, never links: "
            "the archive is damaged or was crafted, and nothing in it was touched"
        ) from err
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError as err:
        os.close(fd)
        raise ArchiveError(
            f"{path}: another process has it open for appending; "
            "close that one or open this one with mode='r'"
        ) from err
    return fd
