"""Checking an archive's chunks against its journal, and recovering after a crash.

A crash (a killed writer, a power loss) leaves at most one uncommitted step
behind: the chunk files of the step being appended, perhaps a torn last
journal line, perhaps an interrupted material replacement. Anything more,
say chunk files of two or more steps past the journal's commits, or chunk
files with an empty journal, cannot come from a crash: the journal lost
records (it was truncated or emptied), and opening stops with
``ArchiveDamaged`` rather than treating committed frames as leftovers.
``rig repair`` rebuilds such a journal from the chunks' own records.

Recovery never deletes: what it does not trust goes to the quarantine.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from rig.archive._errors import ArchiveDamaged
from rig.archive._frames import FrameArray
from rig.archive._index import SessionIndex
from rig.archive._journal import JournalContents
from rig.archive._material import recover_material
from rig.archive._quarantine import Quarantine
from rig.archive._store import read_document

__all__ = ["check_chunks", "check_mirror", "recover"]

log = logging.getLogger(__name__)


def check_chunks(
    path: Path, arrays: Mapping[str, FrameArray], index: SessionIndex, *, journal_events: int
) -> tuple[dict[str, list[int]], dict[str, list[int]]]:
    """Check every committed chunk is present and whole; the leftovers and strays per camera.

    Leftovers are chunk files past a camera's committed frames; strays are
    what sits there under a chunk's name but is not a file (a folder, a link).
    Raises ArchiveDamaged for a missing or resized committed chunk, for a
    stray where a committed one belongs, and for leftovers a crash cannot
    explain (the journal lost records).
    """
    leftovers: dict[str, list[int]] = {}
    strays: dict[str, list[int]] = {}
    for name, array in arrays.items():
        sizes, stray = array.scan_chunks()
        for info, nbytes in index.committed_chunks(name):
            where = f"step {info.step}, camera {name!r}, sub {info.sub}"
            size = sizes.get(info.position)
            if info.position in stray:
                raise ArchiveDamaged(
                    f"{where}: {array.path(info.position)} is {stray[info.position]}, not the "
                    "committed chunk file: the frame is not there"
                )
            if size is None:
                raise ArchiveDamaged(f"{where}: chunk file {array.path(info.position)} is missing")
            if size != nbytes:
                raise ArchiveDamaged(
                    f"{where}: chunk file {array.path(info.position)} has {size} bytes, "
                    f"{nbytes} were committed (truncated or overwritten)"
                )
        extra = sorted(p for p in sizes if p >= index.next_position[name])
        if extra:
            leftovers[name] = extra
        if stray:
            strays[name] = sorted(stray)
    if leftovers:
        _check_leftovers(path, arrays, index, leftovers, journal_events=journal_events)
    return leftovers, strays


def _check_leftovers(path, arrays, index, leftovers, *, journal_events: int) -> None:
    journal = path / "log" / "journal.jsonl"
    found = ", ".join(
        f"frames/{name}: {len(p)} at positions {p[0]}–{p[-1]}" for name, p in leftovers.items()
    )
    repair = f"run `rig repair {path}` to rebuild the journal from the chunks' own records"
    if journal_events == 0:
        raise ArchiveDamaged(
            f"{journal}: the journal is empty, but chunk files are present ({found}); an "
            f"archive's journal is never empty once created: it was emptied or lost; {repair}"
        )
    steps: set[int] = set()
    for name, positions in leftovers.items():
        for position in positions:
            record = arrays[name].read_record(position)
            step = record.get("step") if record else None
            if isinstance(step, dict) and isinstance(step.get("index"), int):
                steps.add(step["index"])
    committed = sorted(steps & set(index.steps))
    if len(steps) > 1 or committed:
        named = sorted(steps)
        shown = f"{named[:5]}…" if len(named) > 5 else str(named)
        raise ArchiveDamaged(
            f"{journal}: {len(index.steps)} steps are committed, but chunk files past them "
            f"({found}) belong to {len(steps)} more step(s) {shown}"
            + (f", {committed} of them committed elsewhere" if committed else "")
            + f"; a crash leaves at most one uncommitted step: the journal lost records "
            f"(truncated); {repair}"
        )


def check_mirror(path: Path, index: SessionIndex) -> None:
    """A calibration mirror newer than the journal means the journal lost records."""
    mirror = read_document(path / "calibration" / "zarr.json", node_type="group")
    version = mirror.get("attributes", {}).get("version", 0)
    if isinstance(version, int) and version > index.calibration_version:
        raise ArchiveDamaged(
            f"{path / 'log' / 'journal.jsonl'}: calibration version "
            f"{index.calibration_version} in the journal, but calibration/zarr.json mirrors "
            f"version {version}, which the journal wrote first: the journal lost records "
            f"(truncated); run `rig repair {path}`"
        )


def recover(
    path: Path,
    arrays: Mapping[str, FrameArray],
    leftovers: Mapping[str, list[int]],
    strays: Mapping[str, list[int]],
    contents: JournalContents,
    quarantine: Quarantine,
) -> dict[str, Any]:
    """Set aside what a crash left half done; what was done, for the ``opened`` event.

    Moves the uncommitted chunk files, the strays under chunk names (a folder
    or link is moved itself, never followed) and the interrupted material
    replacements into ``quarantine`` and keeps a copy of a torn journal tail
    there (the journal cuts it off when it opens).
    """
    recovered: dict[str, Any] = {}
    for kind, found in (("uncommitted_chunks", leftovers), ("not_chunk_files", strays)):
        for name, positions in found.items():
            for position in positions:
                quarantine.move(arrays[name].path(position))
            recovered[f"{kind}/{name}"] = len(positions)
    if contents.torn_bytes:
        journal = path / "log" / "journal.jsonl"
        with open(journal, "rb") as f:
            f.seek(contents.valid_bytes)
            quarantine.keep_bytes("log/journal.jsonl.torn", f.read())
        recovered["torn_journal_bytes"] = contents.torn_bytes
    material = recover_material(path / "material", quarantine)
    if material:
        recovered["material"] = material
    if quarantine.moved:
        recovered["quarantine"] = quarantine.relative_folder
        log.warning("%s: recovery set aside %s", path, recovered)
    return recovered
