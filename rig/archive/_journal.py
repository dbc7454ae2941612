"""The archive's journal: an append-only JSON-lines log that is also its commit log.

Every line is one event ``{"seq", "time", "kind", "payload", "crc32"}`` ending in
a newline; ``crc32`` covers the other four fields in canonical JSON. A step is
committed exactly when its ``"step"`` line is complete on disk, so a reader
trusts a line only if it is newline-terminated, parses, has the right CRC and
the next sequence number. Only the last line may fail that test (a write cut
short by a crash): it is ignored when reading and cut off before appending.
A bad line anywhere else means the file was damaged and is reported.
"""

from __future__ import annotations

import json
import os
import zlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rig.archive._errors import ArchiveError
from rig.archive._records import Event

__all__ = ["Journal", "JournalContents", "read_journal"]


def _body(seq: int, time: float, kind: str, payload: Any) -> str:
    return json.dumps(
        {"seq": seq, "time": time, "kind": kind, "payload": payload},
        sort_keys=True,
        separators=(",", ":"),
        allow_nan=False,
    )


def _line(seq: int, time: float, kind: str, payload: Any) -> bytes:
    body = _body(seq, time, kind, payload)
    record = body[:-1] + f',"crc32":{zlib.crc32(body.encode())}}}'
    return record.encode() + b"\n"


def _parse(line: bytes, expected_seq: int) -> Event | None:
    """The event on ``line``, or None when the line is not a valid record."""
    try:
        record = json.loads(line)
        crc = record.pop("crc32")
        event = Event(record["seq"], record["time"], record["kind"], record["payload"])
    except (ValueError, KeyError, TypeError, AttributeError):
        return None
    if set(record) != {"seq", "time", "kind", "payload"} or event.seq != expected_seq:
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

    Raises ArchiveError when the file is missing or a record other than the
    last one is invalid (the line number and byte offset are in the message).
    """
    try:
        data = path.read_bytes()
    except FileNotFoundError as err:
        raise ArchiveError(f"{path.parent}: missing journal {path.name}") from err
    events: list[Event] = []
    offset = 0
    while offset < len(data):
        end = data.find(b"\n", offset)
        event = None if end < 0 else _parse(data[offset:end], len(events))
        if event is None:
            if end >= 0 and end + 1 < len(data):
                raise ArchiveError(
                    f"{path}: line {len(events) + 1} (byte {offset}) is not a valid record "
                    f"(seq {len(events)} expected) but more records follow: the journal is "
                    "damaged"
                )
            break
        events.append(event)
        offset = end + 1
    return JournalContents(events, valid_bytes=offset, torn_bytes=len(data) - offset)


class Journal:
    """Appends events to the journal file; one writer at a time.

    Opening cuts off a torn last line, so the next record starts on a fresh
    line. With ``fsync`` each append is on disk when ``append`` returns.
    """

    def __init__(self, path: Path, contents: JournalContents, *, fsync: bool):
        self.path = path
        self._fsync = fsync
        self._next_seq = len(contents.events)
        self._fd = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
        if contents.torn_bytes:
            os.ftruncate(self._fd, contents.valid_bytes)
            os.fsync(self._fd)

    def append(self, kind: str, payload: dict[str, Any], *, time: float) -> Event:
        """Write one event as a single ``write`` and return it."""
        if self._fd < 0:
            raise ArchiveError(f"{self.path}: the journal is closed")
        event = Event(self._next_seq, time, kind, payload)
        line = memoryview(_line(event.seq, time, kind, payload))
        while line:
            line = line[os.write(self._fd, line) :]
        if self._fsync:
            os.fsync(self._fd)
        self._next_seq += 1
        return event

    def close(self) -> None:
        if self._fd >= 0:
            os.close(self._fd)
            self._fd = -1
