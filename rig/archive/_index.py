"""The in-memory index of an archive, rebuilt from its journal on every open.

Holds the committed steps, the frame table (step, camera, sub → position in
the camera's array) and the current calibration, and checks that the journal
describes a consistent archive: known cameras, frames stored contiguously in
commit order, no step committed twice.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from rig.archive._errors import ArchiveDamaged, ArchiveError, StepAlreadyCommitted
from rig.archive._records import Event, FrameFormat, FrameInfo, FrameRecord, StepRecord

__all__ = ["FRAME_TABLE_DTYPE", "SessionIndex"]

#: Fields of ``Archive.frame_table()``.
FRAME_TABLE_DTYPE = np.dtype(
    [
        ("step", np.int64),
        ("camera", "U64"),
        ("sub", np.int64),
        ("exposure_s", np.float64),
        ("timestamp", np.float64),
        ("position", np.int64),
    ]
)


class SessionIndex:
    """Committed steps and frames of one archive."""

    def __init__(self, path: Path, cameras: Mapping[str, FrameFormat], events: Sequence[Event]):
        self.path = path
        self.cameras = cameras
        self.steps: dict[int, StepRecord] = {}
        self.next_position = dict.fromkeys(cameras, 0)
        self.calibration: dict[str, Any] = {}
        self.calibration_version = 0
        # (step, camera) → {sub: (FrameInfo, chunk bytes)}, in commit order.
        self._frames: dict[tuple[int, str], dict[int, tuple[FrameInfo, int]]] = {}
        for event in events:
            if event.kind == "step":
                self.add_step(event)
            elif event.kind == "calibration":
                self.add_calibration(event)

    def add_calibration(self, event: Event) -> None:
        """Make the calibration of journal ``event`` (kind ``"calibration"``) current."""
        try:
            version, calibration = event.payload["version"], event.payload["calibration"]
        except (KeyError, TypeError) as err:
            raise ArchiveDamaged(f"{self.path}: journal seq {event.seq}: bad calibration") from err
        if version != self.calibration_version + 1 or not isinstance(calibration, dict):
            raise ArchiveDamaged(
                f"{self.path}: journal seq {event.seq}: calibration version {version!r}, "
                f"expected {self.calibration_version + 1}"
            )
        self.calibration, self.calibration_version = calibration, version

    def add_step(self, event: Event) -> None:
        """Index the committed step of journal ``event`` (kind ``"step"``)."""
        where = f"{self.path}: journal seq {event.seq}"
        try:
            step = StepRecord.from_json(event.payload["step"])
            rows = {
                camera: [(int(s), float(e), float(t), int(p), int(n)) for s, e, t, p, n in frames]
                for camera, frames in event.payload["frames"].items()
            }
        except (KeyError, TypeError, ValueError) as err:
            raise ArchiveDamaged(f"{where}: malformed step record: {err!r}") from err
        where = f"{where} (step {step.index})"
        if step.index in self.steps:
            raise ArchiveDamaged(f"{where}: step {step.index} is committed twice")
        if set(rows) != set(step.cameras) or not set(rows) <= set(self.cameras):
            raise ArchiveDamaged(
                f"{where}: frames for cameras {sorted(rows)}, step lists {list(step.cameras)}, "
                f"archive has {sorted(self.cameras)}"
            )
        for camera, frames in rows.items():
            entries = {}
            for offset, (sub, exposure_s, timestamp, position, nbytes) in enumerate(frames):
                expected = self.next_position[camera] + offset
                if position != expected or sub in entries or nbytes <= 0:
                    raise ArchiveDamaged(
                        f"{where}: camera {camera!r} sub {sub} at position {position} "
                        f"({nbytes} bytes); expected a new sub at position {expected}"
                    )
                info = FrameInfo(step.index, camera, sub, exposure_s, timestamp, position)
                entries[sub] = (info, nbytes)
            self._frames[(step.index, camera)] = entries
        for camera, frames in rows.items():
            self.next_position[camera] += len(frames)
        self.steps[step.index] = step

    def check_new_step(self, step: StepRecord, frames: Mapping[str, Sequence[FrameRecord]]) -> None:
        """Raise unless ``step`` with ``frames`` (already FrameRecords) can be appended."""
        if not isinstance(step, StepRecord):
            raise ArchiveError(f"{self.path}: expected a StepRecord, got {type(step).__name__}")
        where = f"{self.path}: step {step.index}"
        if step.index in self.steps:
            next_index = max(self.steps) + 1
            raise StepAlreadyCommitted(
                f"{where} is already committed; nothing is captured twice. "
                f"Continue with a step not in committed_steps() (next after the last: "
                f"{next_index})",
                index=step.index,
                next_index=next_index,
            )
        unknown = [c for c in step.cameras if c not in self.cameras]
        if unknown:
            raise ArchiveError(
                f"{where}: unknown camera(s) {unknown}; archive has {sorted(self.cameras)}"
            )
        if set(frames) != set(step.cameras):
            raise ArchiveError(
                f"{where}: frames given for cameras {sorted(frames)}, but the step lists "
                f"{list(step.cameras)}"
            )
        for camera, records in frames.items():
            if not records:
                raise ArchiveError(f"{where}, camera {camera!r}: no frames")
            subs = [r.sub for r in records]
            if len(set(subs)) != len(subs):
                raise ArchiveError(f"{where}, camera {camera!r}: repeated sub-indices {subs}")
            for r in records:
                bad = _bad_frame_field(r)
                if bad:
                    raise ArchiveError(f"{where}, camera {camera!r}, sub {r.sub!r}: {bad}")

    def lookup(self, step: int, camera: str, sub: int) -> tuple[FrameInfo, int]:
        """FrameInfo and committed chunk size of one frame, or ArchiveError."""
        entries = self._frames.get((step, camera))
        if entries is None or sub not in entries:
            if step not in self.steps:
                raise ArchiveError(
                    f"{self.path}: step {step} is not committed ({len(self.steps)} steps are)"
                )
            if camera not in self.steps[step].cameras:
                raise ArchiveError(
                    f"{self.path}: step {step} has no frames of camera {camera!r}; "
                    f"it has {list(self.steps[step].cameras)}"
                )
            raise ArchiveError(
                f"{self.path}: step {step}, camera {camera!r} has no sub {sub}; "
                f"it has {sorted(entries)}"
            )
        return entries[sub]

    def frame_infos(self) -> list[FrameInfo]:
        """Every committed frame, by step index, camera (step order) and sub."""
        infos = []
        for index in sorted(self.steps):
            for camera in self.steps[index].cameras:
                entries = self._frames[(index, camera)]
                infos.extend(entries[sub][0] for sub in sorted(entries))
        return infos

    def committed_chunks(self, camera: str) -> list[tuple[FrameInfo, int]]:
        """(FrameInfo, chunk bytes) of every committed frame of ``camera``."""
        return [
            e for (_, c), entries in self._frames.items() if c == camera for e in entries.values()
        ]


def _bad_frame_field(record: FrameRecord) -> str | None:
    if (
        not isinstance(record.sub, int | np.integer)
        or isinstance(record.sub, bool)
        or record.sub < 0
    ):
        return f"sub = {record.sub!r}: must be an int ≥ 0"
    for name in ("exposure_s", "timestamp"):
        value = getattr(record, name)
        if not isinstance(value, float | int | np.floating | np.integer) or not math.isfinite(
            value
        ):
            return f"{name} = {value!r}: must be a finite number"
    if record.exposure_s < 0:
        return f"exposure_s = {record.exposure_s}: must be ≥ 0"
    return None
