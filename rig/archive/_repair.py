"""Rebuilding a damaged journal from what survives: its whole lines and the chunks' records.

``repair_archive`` keeps every journal line whose CRC holds (whatever its
place), and rebuilds each step the journal lost from the records its chunk
files carry (see ``_frames``): a step is rebuilt when every frame its records
announce is present and decodes (zstd's content checksum). Steps are then
laid out in the order their frames sit in each camera's array. Everything
else (lines that are not whole records, chunk files of incomplete steps or
without a record, the old journal itself) goes to the quarantine.

What cannot be rebuilt: events other than steps whose lines are lost (the
``opened``/``closed`` history, ``scan`` tilts, ``material`` records, older
calibration versions; the current calibration survives in its mirror), and
steps whose chunk files carry no record. Committed frames that are missing
or resized cannot be rebuilt either: repair then changes nothing.
"""

from __future__ import annotations

import logging
import os
import time
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rig.archive._errors import ArchiveDamaged, ArchiveError
from rig.archive._frames import FrameArray
from rig.archive._journal import encode_event, salvage_journal
from rig.archive._layout import JOURNAL, lock_writer, read_layout
from rig.archive._quarantine import Quarantine
from rig.archive._records import Event, StepRecord
from rig.archive._store import chunk_name, read_document, write_atomic

__all__ = ["RepairReport", "repair_archive"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class RepairReport:
    """What ``repair_archive`` did.

    ``changed`` is False when the archive opened cleanly and was left alone;
    ``journal_rebuilt`` is False when only strays (folders or links under chunk
    names) were set aside.
    ``kept_records`` journal lines were kept; ``rebuilt_steps`` were rebuilt
    from chunk records; ``set_aside`` lists what went to ``quarantine`` (a
    folder relative to the archive, None when nothing did); ``lost`` says
    what could not be rebuilt.
    """

    path: Path
    changed: bool
    kept_records: int
    committed_steps: int
    rebuilt_steps: tuple[int, ...] = ()
    quarantine: str | None = None
    set_aside: tuple[str, ...] = ()
    lost: tuple[str, ...] = ()
    journal_rebuilt: bool = True

    def to_json(self) -> dict[str, Any]:
        return {
            "kept_records": self.kept_records,
            "committed_steps": self.committed_steps,
            "rebuilt_steps": list(self.rebuilt_steps),
            "quarantine": self.quarantine,
            "set_aside": len(self.set_aside),
            "lost": list(self.lost),
        }


@dataclass
class _Step:
    """A step to lay out: from a journal record or rebuilt from chunk records."""

    record: StepRecord
    rows: dict[str, list[list]]  # camera → [sub, exposure_s, timestamp, position, bytes]
    time: float
    from_chunks: bool

    def fits(self, next_position: dict[str, int]) -> bool:
        return all(rows[0][3] == next_position[c] for c, rows in self.rows.items())


def repair_archive(path: str | os.PathLike, *, fsync: bool = True) -> RepairReport:
    """Rebuild the journal of the archive at ``path`` where it lost or garbled records.

    Returns the report; an archive that opens cleanly is left untouched. Raises
    ArchiveError when the damage is not in the journal (metadata, committed
    frames) or another process has the archive open for appending.
    """
    from rig.archive.archive import Archive

    path = Path(path)
    if not path.is_dir():
        raise ArchiveError(f"{path}: no archive here (not a directory)")
    try:
        with Archive.open(path) as archive:
            events, steps = len(archive.events()), len(archive.committed_steps())
        strays = [
            f"frames/{name}/{chunk_name(position)}"
            for name, array in read_layout(path).arrays.items()
            for position in sorted(array.scan_chunks().strays)
        ]
        if not strays:
            return RepairReport(path, changed=False, kept_records=events, committed_steps=steps)
        # Folders or links under chunk names past the commits: a writable open sets them aside.
        with Archive.open(path, mode="a", fsync=fsync) as archive:
            quarantine = archive.recovered.get("quarantine")
        return RepairReport(
            path,
            changed=True,
            kept_records=events,
            committed_steps=steps,
            quarantine=quarantine,
            set_aside=tuple(strays),
            journal_rebuilt=False,
        )
    except ArchiveDamaged as err:
        log.info("%s: repairing: %s", path, err)
    lock = lock_writer(path)
    try:
        report = _rebuild(path, fsync=fsync)
    finally:
        os.close(lock)
    # A writable open checks the result, trims the arrays' shapes and logs the opening.
    Archive.open(path, mode="a", fsync=fsync).close()
    return report


def _rebuild(path: Path, *, fsync: bool) -> RepairReport:
    layout = read_layout(path)
    journal = path / JOURNAL
    data = journal.read_bytes() if journal.exists() else b""
    events, bad_lines = salvage_journal(data)
    lost = [
        f"journal byte {offset}: {len(line)} bytes are not a whole record"
        for offset, line in bad_lines
    ]
    scans = {name: array.scan_chunks() for name, array in layout.arrays.items()}
    sizes = {name: scan.sizes for name, scan in scans.items()}
    steps, others, calibration_version = _journal_steps(path, layout.arrays, sizes, events, lost)
    claimed = {(c, row[3]) for s in steps.values() for c, rows in s.rows.items() for row in rows}
    rebuilt = _steps_from_chunks(path, layout.arrays, sizes, claimed, set(steps), lost)
    candidates = [*steps.values(), *rebuilt.values()]
    placed, next_position = _lay_out(candidates, layout.cameras)
    placed_ids = {id(step) for step in placed}
    for step in candidates:
        if id(step) not in placed_ids:
            lost.append(f"step {step.record.index}: its frames do not follow the steps before them")
    quarantine = Quarantine(path, fsync=fsync)
    if data:
        quarantine.keep_bytes(JOURNAL, data)
    for name, array in layout.arrays.items():
        for position in sorted(p for p in sizes[name] if p >= next_position[name]):
            quarantine.move(array.path(position))
        for position in sorted(scans[name].strays):  # a folder or link, never followed
            quarantine.move(array.path(position))
    new_events = _merge(others, placed)
    mirror = _mirror_calibration(path, calibration_version, lost)
    if mirror is not None:
        new_events.append(mirror)
    report = RepairReport(
        path,
        changed=True,
        kept_records=len(others) + sum(not s.from_chunks for s in placed),
        committed_steps=len(placed),
        rebuilt_steps=tuple(sorted(s.record.index for s in placed if s.from_chunks)),
        quarantine=quarantine.relative_folder if quarantine.moved else None,
        set_aside=tuple(quarantine.moved),
        lost=tuple(lost),
    )
    new_events.append(("repaired", report.to_json(), None))
    lines = [encode_event(seq, t if t is not None else time.time(), kind, payload)
             for seq, (kind, payload, t) in enumerate(new_events)]  # fmt: skip
    write_atomic(journal, b"".join(lines), fsync=fsync)
    log.info("%s: journal rebuilt: %s", path, report.to_json())
    return report


def _journal_steps(path, arrays, sizes, events: list[Event], lost: list[str]):
    """The journal's whole step records, its other events and its calibration version.

    Raises ArchiveDamaged when a committed frame is missing or resized: a
    journal rebuild cannot restore frames.
    """
    steps: dict[int, _Step] = {}
    others: list[tuple[str, Any, float]] = []
    version = 0
    for event in events:
        if event.kind == "step":
            step = _parse_step(event, arrays)
            if step is None or step.record.index in steps:
                lost.append(f"journal seq {event.seq}: a step record that repeats or is malformed")
                continue
            for camera, rows in step.rows.items():
                for row in rows:
                    if sizes[camera].get(row[3]) != row[4]:
                        raise ArchiveDamaged(
                            f"{path}: committed step {step.record.index}, camera {camera!r}, "
                            f"sub {row[0]}: chunk file {arrays[camera].path(row[3])} is "
                            f"missing or resized; repair rebuilds journals, not frames"
                        )
            steps[step.record.index] = step
            continue
        if event.kind == "calibration":
            if event.payload.get("version") != version + 1:
                lost.append(f"journal seq {event.seq}: calibration out of order, not kept")
                continue
            version += 1
        others.append((event.kind, event.payload, event.time))
    return steps, others, version


def _parse_step(event: Event, arrays) -> _Step | None:
    try:
        record = StepRecord.from_json(event.payload["step"])
        rows = {
            c: [[int(s), float(e), float(t), int(p), int(n)] for s, e, t, p, n in frames]
            for c, frames in event.payload["frames"].items()
        }
    except (ArchiveError, KeyError, TypeError, ValueError):
        return None
    if not rows or set(rows) - set(arrays) or set(rows) != set(record.cameras):
        return None
    if any(not r or not _contiguous(r) for r in rows.values()):
        return None
    return _Step(record, rows, event.time, from_chunks=False)


def _contiguous(rows: list[list]) -> bool:
    positions = [row[3] for row in rows]
    subs = [row[0] for row in rows]
    return positions == list(range(positions[0], positions[0] + len(rows))) and len(
        set(subs)
    ) == len(subs)


def _steps_from_chunks(path, arrays: dict[str, FrameArray], sizes, claimed, journal_steps, lost):
    """Steps rebuilt from the records of chunk files no journal step claims."""
    found: dict[int, dict[str, list]] = defaultdict(lambda: defaultdict(list))
    announced: dict[int, tuple[dict, dict]] = {}
    for name, array in arrays.items():
        for position, size in sorted(sizes[name].items()):
            if (name, position) in claimed:
                continue
            record = array.read_record(position)
            step = record.get("step") if record else None
            if not isinstance(step, dict) or step.get("index") in journal_steps:
                continue
            try:
                key = int(step["index"])
                row = [int(record["sub"]), float(record["exposure_s"]),
                       float(record["timestamp"]), position, size]  # fmt: skip
            except (KeyError, TypeError, ValueError):
                continue
            found[key][name].append(row)
            announced.setdefault(key, (step, record.get("frames")))
    steps: dict[int, _Step] = {}
    for index, rows in sorted(found.items()):
        step_json, counts = announced[index]
        problem = _incomplete(rows, counts)
        if problem is None:
            problem = _undecodable(path, arrays, index, rows)
        if problem is not None:
            lost.append(f"step {index} (from chunk records): {problem}")
            continue
        rows = {c: sorted(r, key=lambda row: row[3]) for c, r in rows.items()}
        committed_at = max(
            arrays[c].path(row[3]).stat().st_mtime for c, r in rows.items() for row in r
        )
        try:
            record = StepRecord.from_json({**step_json, "committed_at": committed_at})
        except (ArchiveError, KeyError, TypeError, ValueError) as err:
            lost.append(f"step {index} (from chunk records): bad step record: {err}")
            continue
        if set(record.cameras) != set(rows) or not all(map(_contiguous, rows.values())):
            lost.append(f"step {index} (from chunk records): frames not stored together")
            continue
        steps[index] = _Step(record, rows, committed_at, from_chunks=True)
    return steps


def _incomplete(rows: dict[str, list], counts: Any) -> str | None:
    if not isinstance(counts, dict) or set(counts) != set(rows):
        return f"frames of cameras {sorted(rows)} present, the step has {counts!r}"
    for camera, n in counts.items():
        if len(rows[camera]) != n:
            return f"{len(rows[camera])} of {n} frames of camera {camera!r} present"
    return None


def _undecodable(path, arrays, index, rows) -> str | None:
    for camera, camera_rows in rows.items():
        for row in camera_rows:
            where = f"{path}: step {index}, camera {camera!r}, sub {row[0]}"
            try:
                arrays[camera].read(row[3], nbytes=row[4], where=where)
            except ArchiveError as err:
                return str(err)
    return None


def _lay_out(steps: list[_Step], cameras) -> tuple[list[_Step], dict[str, int]]:
    """Order the steps so each camera's frames are at positions 0, 1, 2, … in turn.

    Of the steps that fit next, the one started first comes first: the order
    a session commits them in, as far as the frames' positions allow.
    """
    by_start: dict[tuple[str, int], list[_Step]] = defaultdict(list)
    for step in steps:
        for camera, rows in step.rows.items():
            by_start[(camera, rows[0][3])].append(step)
    next_position = dict.fromkeys(cameras, 0)
    placed: list[_Step] = []
    while True:
        fitting = [
            step
            for camera in cameras
            for step in by_start.get((camera, next_position[camera]), [])
            if step.fits(next_position)
        ]
        if not fitting:
            return placed, next_position
        step = min(fitting, key=lambda s: (s.record.started_at, s.record.index))
        placed.append(step)
        for camera, rows in step.rows.items():
            by_start[(camera, rows[0][3])].remove(step)
            next_position[camera] += len(rows)


def _merge(others: list[tuple[str, Any, float]], placed: list[_Step]) -> list[tuple]:
    """Kept events and laid-out steps in one list, by time, each keeping its own order."""
    merged: list[tuple] = []
    i = 0
    for step in placed:
        while i < len(others) and others[i][2] <= step.time:
            merged.append(others[i])
            i += 1
        rows = step.rows
        payload = {"step": step.record.to_json(), "frames": rows}
        if step.from_chunks:
            payload["rebuilt_from"] = "chunk records"
        merged.append(("step", payload, step.time))
    merged.extend(others[i:])
    return merged


def _mirror_calibration(path: Path, version: int, lost: list[str]) -> tuple | None:
    """A calibration record from the mirror when the journal lost newer versions."""
    mirror = read_document(path / "calibration" / "zarr.json", node_type="group")
    attributes = mirror.get("attributes", {})
    mirrored = attributes.get("version")
    if not isinstance(mirrored, int) or mirrored <= version:
        return None
    if mirrored > version + 1:
        lost.append(f"calibration versions {version + 1}–{mirrored - 1} (only the last survives)")
    payload = {
        "version": version + 1,
        "calibration": attributes.get("calibration", {}),
        "rebuilt_from": f"calibration/zarr.json (version {mirrored})",
    }
    return ("calibration", payload, None)
