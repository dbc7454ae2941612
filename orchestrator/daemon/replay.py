"""Replay: a recorded session run back through the daemon.

``ReplayDevices`` stands where the rig's drivers stand. It serves the frames
an archive recorded, step by step, and checks that the session asks for what
was recorded: the same moves (within the read-back tolerance), the same lamp
or laser, cameras and exposures. Workers downstream see the same frame stream
as they saw live. ``speed`` paces the steps by their recorded start times
(``speed=2`` twice as fast); ``speed=None`` replays as fast as the archive reads.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from drivers.errors import DeviceError
from orchestrator.daemon.scan import Captured, Scan
from rig.archive import Archive, StepRecord
from rig.clock import Clock
from rig.config import RigConfig

__all__ = ["MOVE_TOLERANCE_DEG", "ReplayDevices", "replay_factory"]

#: How far a requested move may be from the recorded read-back (encoder ticks, steps).
MOVE_TOLERANCE_DEG = 0.1
_DEVICE = "replay"


class ReplayDevices:
    """A device set whose frames come from ``source`` (an open archive)."""

    def __init__(self, source: Archive, *, clock: Clock, speed: float | None = None):
        if speed is not None and not speed > 0:
            raise ValueError(f"replay speed={speed} must be > 0 (or None for as fast as possible)")
        self._source = source
        self._clock = clock
        self._speed = speed
        self._steps: list[StepRecord] = source.step_table()
        if not self._steps:
            raise DeviceError(_DEVICE, "open", f"{source.path} has no committed step to replay")
        self._frames = source.frame_table()
        self._tilts = {e.payload["step"]: e.payload["tilts_deg"] for e in source.events("scan")}
        self._next = 0  # index into self._steps of the step the next move starts
        self._current: StepRecord | None = None
        self._t0: float | None = None
        self._position = {"turntable_deg": 0.0, "arc_deg": 0.0}
        self._lit: tuple[str, object] | None = None  # ("lamp", id) or ("laser", mount)

    # -- motion and sources ------------------------------------------------------------
    def home(self, *, laser: bool) -> None:
        self._position = {"turntable_deg": 0.0, "arc_deg": 0.0}

    def place(self, pose) -> dict[str, float]:
        """:meth:`move` to a step's pose (a rig of axes': the Bonn lab's are not replayed)."""
        return self.move(turntable_deg=pose.turntable_deg, arc_deg=pose.arc_deg)

    def move(self, *, turntable_deg: float, arc_deg: float) -> dict[str, float]:
        """Start the next recorded step; its read-back positions must match the request."""
        if self._next >= len(self._steps):
            raise DeviceError(
                _DEVICE, "move",
                f"to turntable {turntable_deg:.3f}°, arc {arc_deg:.3f}°: the recording has "
                f"only {len(self._steps)} committed step(s), all replayed",
            )  # fmt: skip
        record = self._steps[self._next]
        recorded = record.actuators
        for axis, wanted in (("turntable_deg", turntable_deg), ("arc_deg", arc_deg)):
            got = recorded.get(axis)
            if got is None or abs(_wrap(got - wanted)) > MOVE_TOLERANCE_DEG:
                raise DeviceError(
                    _DEVICE, "move",
                    f"step {record.index}: the plan moves {axis} to {wanted:.3f} but the "
                    f"recording has {got}; the archive does not match its plan",
                )  # fmt: skip
        self._pace(record)
        self._current = record
        self._next += 1
        self._position = {k: float(recorded[k]) for k in ("turntable_deg", "arc_deg")}
        return dict(self._position)

    def forget_position(self) -> None:
        """Nothing to forget: the recording's positions are what they are."""

    def lamp(self, lamp_id: str, on: bool) -> None:
        self._check_source("lamp", lamp_id, on, self._record("lamp").lamp)

    def laser(self, mount: int, on: bool) -> None:
        self._check_source("laser", mount, on, self._record("laser").laser)

    def _check_source(self, kind: str, wanted, on: bool, recorded) -> None:
        if on and wanted != recorded:
            raise DeviceError(
                _DEVICE, kind,
                f"step {self._current.index}: the plan lights {kind} {wanted!r}, the recording "
                f"{recorded!r}",
            )  # fmt: skip
        self._lit = (kind, wanted) if on else None

    # -- frames ------------------------------------------------------------------------
    def capture(
        self, cameras: Sequence[str], exposures_s: Sequence[float]
    ) -> dict[str, list[Captured]]:
        record = self._record("capture")
        if tuple(exposures_s) != tuple(record.exposures_s):
            raise DeviceError(
                _DEVICE, "capture",
                f"step {record.index}: exposures {tuple(exposures_s)} s, recorded "
                f"{tuple(record.exposures_s)} s",
            )  # fmt: skip
        return self._recorded_frames(record, cameras, len(exposures_s))

    def scan(
        self,
        cameras: Sequence[str],
        *,
        tilt_deg: tuple[float, float],
        frames: int,
        exposure_s: float,
    ) -> Scan:
        record = self._record("scan")
        tilts = self._tilts.get(record.index)
        if tilts is None:
            raise DeviceError(_DEVICE, "scan", f"step {record.index}: no scan event recorded")
        if len(tilts) != frames:
            raise DeviceError(
                _DEVICE, "scan",
                f"step {record.index}: the plan scans {frames} frames, the recording {len(tilts)}",
            )  # fmt: skip
        frames_by_camera = self._recorded_frames(record, cameras, frames)
        return Scan(frames_by_camera, [float(t) for t in tilts], record.flags)

    def _recorded_frames(
        self, record: StepRecord, cameras: Sequence[str], n: int
    ) -> dict[str, list[Captured]]:
        if tuple(cameras) != tuple(record.cameras):
            raise DeviceError(
                _DEVICE, "capture",
                f"step {record.index}: cameras {tuple(cameras)}, recorded {record.cameras}",
            )  # fmt: skip
        rows = self._frames[self._frames["step"] == record.index]
        out: dict[str, list[Captured]] = {}
        for camera in cameras:
            mine = sorted(rows[rows["camera"] == camera], key=lambda r: int(r["sub"]))
            if len(mine) != n:
                raise DeviceError(
                    camera, "capture",
                    f"step {record.index}: {n} frame(s) wanted, {len(mine)} recorded",
                )  # fmt: skip
            out[camera] = [self._captured(record.index, camera, row) for row in mine]
        return out

    def _captured(self, step: int, camera: str, row) -> Captured:
        sub = int(row["sub"])
        image = self._source.read_frame(step, camera, sub)
        return Captured(image, sub, float(row["exposure_s"]), float(row["timestamp"]))

    # -- the rest of the DeviceSet ---------------------------------------------------------
    def all_off(self) -> None:
        self._lit = None

    def telemetry(self) -> dict:
        lamps = [self._lit[1]] if self._lit is not None and self._lit[0] == "lamp" else []
        return {**self._position, "lamps_on": lamps}

    def close(self) -> None:
        self._source.close()

    def _record(self, operation: str) -> StepRecord:
        if self._current is None:
            raise DeviceError(_DEVICE, operation, "no step started: move first")
        return self._current

    def _pace(self, record: StepRecord) -> None:
        if self._speed is None:
            return
        first = self._steps[0].started_at
        if self._t0 is None:
            self._t0 = self._clock.now()
        due = self._t0 + (record.started_at - first) / self._speed
        self._clock.sleep(max(0.0, due - self._clock.now()))


def _wrap(deg: float) -> float:
    return (deg + 180.0) % 360.0 - 180.0


def replay_factory(path: str | Path, *, speed: float | None = None):
    """A ``DeviceFactory`` for the daemon that replays the archive at ``path``."""

    def open_replay(config: RigConfig, *, clock: Clock, scale: float = 1.0, laser: bool = True):
        return ReplayDevices(Archive.open(path, mode="r"), clock=clock, speed=speed)

    return open_replay
