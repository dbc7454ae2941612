"""The archive's journal: an append-only JSON-lines log that is also its commit log.

Every line is one event ``{"seq", "time", "kind", "payload", "crc32"}`` ending in
a newline; ``crc32`` covers the other four fields in canonical JSON. A step is
committed exactly when its ``"step"`` line is complete on disk, so a reader
trusts a line only if it is newline-terminated, parses, has the right CRC and
the next sequence number. Only the last line may fail that test (a write cut
short by a crash): it is ignored when reading and cut off before appending.
A bad line anywhere else means the file was damaged and is reported.

A write that fails (a full disk) is cut back off to the last whole line and
the file ``fsync``-ed, so the journal stays readable and appendable once
space returns.
"""

from __future__ import annotations

import json
import os
import zlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rig.archive._errors import ArchiveDamaged, ArchiveError, os_failure
from rig.archive._records import Event

__all__ = ["Journal", "JournalContents", "encode_event", "read_journal", "salvage_journal"]


def _body(seq: int, time: float, kind: str, payload: Any) -> str:
    return json.dumps(
        {"seq": seq, "time": time, "kind": kind, "payload": payload},
        sort_keys=True,
        separators=(",", ":"),
        allow_nan=False,
    )


def encode_event(seq: int, time: float, kind: str, payload: Any) -> bytes:
    """One journal line: the event in canonical JSON with its CRC, newline-terminated."""
    body = _body(seq, time, kind, payload)
    record = body[:-1] + f',"crc32":{zlib.crc32(body.encode())}}}'
    return record.encode() + b"\n"


def _parse(line: bytes, expected_seq: int | None) -> Event | None:
    """The event on ``line``, or None when the line is not a valid record.

    ``expected_seq`` None accepts any sequence number (salvaging a damaged journal).
    """
    try:
        record = json.loads(line)
        crc = record.pop("crc32")
        event = Event(record["seq"], record["time"], record["kind"], record["payload"])
    except (ValueError, KeyError, TypeError, AttributeError):
        return None
    if set(record) != {"seq", "time", "kind", "payload"}:
        return None
    if expected_seq is not None and event.seq != expected_seq:
        return None
    if zlib.crc32(_body(event.seq, event.time, event.kind, event.payload).encode()) != crc:
        return None
    return event


@dataclass(frozen=True)
class JournalContents:
    """The valid events of a journal, and where its valid part ends."""

    events: list[Event]
    valid_bytes: int
    torn_bytes: int


def read_journal(path: Path) -> JournalContents:
    """Read every valid event of the journal at ``path``.

    Raises ArchiveDamaged when the file is missing or a record other than the
    last one is invalid (the line number and byte offset are in the message).
    """
    try:
        data = path.read_bytes()
    except FileNotFoundError as err:
        raise ArchiveDamaged(
            f"{path.parent}: missing journal {path.name}; `rig repair` rebuilds it"
        ) from err
    events: list[Event] = []
    offset = 0
    while offset < len(data):
        end = data.find(b"\n", offset)
        event = None if end < 0 else _parse(data[offset:end], len(events))
        if event is None:
            if end >= 0 and end + 1 < len(data):
                raise ArchiveDamaged(
                    f"{path}: line {len(events) + 1} (byte {offset}) is not a valid record "
                    f"(seq {len(events)} expected) but more records follow: the journal is "
                    "damaged; `rig repair` rebuilds it"
                )
            break
        events.append(event)
        offset = end + 1
    return JournalContents(events, valid_bytes=offset, torn_bytes=len(data) - offset)


def salvage_journal(data: bytes) -> tuple[list[Event], list[tuple[int, bytes]]]:
    """Every line of ``data`` that is a whole record by its CRC, whatever its ``seq``.

    Returns the records in file order and the other lines as (byte offset, bytes).
    """
    events: list[Event] = []
    bad: list[tuple[int, bytes]] = []
    offset = 0
    for line in data.splitlines(keepends=True):
        event = _parse(line.rstrip(b"\n"), None) if line.endswith(b"\n") else None
        if event is None:
            bad.append((offset, line))
        else:
            events.append(event)
        offset += len(line)
    return events, bad


class Journal:
    """Appends events to the journal file; one writer at a time.

    Opening cuts off a torn last line, so the next record starts on a fresh
    line. With ``fsync`` each append is on disk when ``append`` returns; a
    failed append leaves the file as it was before it.
    """

    def __init__(self, path: Path, contents: JournalContents, *, fsync: bool):
        self.path = path
        self._fsync = fsync
        self._next_seq = len(contents.events)
        self._size = contents.valid_bytes
        self._fd = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
        if contents.torn_bytes:
            os.ftruncate(self._fd, contents.valid_bytes)
            os.fsync(self._fd)

    def append(self, kind: str, payload: dict[str, Any], *, time: float) -> Event:
        """Write one event as a single ``write`` and return it.

        Raises ArchiveFull (disk full) or ArchiveError after cutting a partial
        write back off: the journal then ends with its last whole line.
        """
        if self._fd < 0:
            raise ArchiveError(f"{self.path}: the journal is closed")
        event = Event(self._next_seq, time, kind, payload)
        line = encode_event(event.seq, time, kind, payload)
        try:
            rest = memoryview(line)
            while rest:
                rest = rest[os.write(self._fd, rest) :]
            if self._fsync:
                os.fsync(self._fd)
        except OSError as err:
            self._cut_back(err)
            raise os_failure(
                err, self.path, doing=f"a {kind!r} record", needed_bytes=len(line)
            ) from err
        self._size += len(line)
        self._next_seq += 1
        return event

    def _cut_back(self, err: OSError) -> None:
        # Shrinking a file needs no free space; without this the next record
        # would land after a torn line and the journal would read as damaged.
        try:
            os.ftruncate(self._fd, self._size)
            os.fsync(self._fd)
        except OSError as cut_err:
            raise ArchiveError(
                f"{self.path}: a record failed ({err.strerror}) and cutting its partial "
                f"line off failed too ({cut_err.strerror}); the next writable open sets "
                "the torn line aside"
            ) from cut_err

    def close(self) -> None:
        if self._fd >= 0:
            os.close(self._fd)
            self._fd = -1
