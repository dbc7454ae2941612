"""One step against the devices: move, light, capture, commit, switch off, stream.

``StepRunner.move`` sends the step's pose to the devices (a Wang rig's two axes
at once; a Bonn lab's arm and rail) and returns when they settled.
``StepRunner.expose`` then switches the step's lamp or laser on, triggers the
cameras (or sweeps the laser sheet past them), commits the frames to the archive
in one atomic append, switches the source off (a lamp the following step uses
too stays lit) and streams the frames to the workers. Between the two the session
decides whether to go on: an abort during a long move lights nothing.
"""

from __future__ import annotations

import itertools

from orchestrator.daemon.checks import checked_capture, flagged_payload
from orchestrator.daemon.devices import Captured, DeviceSet
from orchestrator.daemon.stream import SessionOutbox
from orchestrator.wire.protocol import ArraySpec, FrameHeader
from rig.archive import Archive, FrameFlag, FrameRecord, StepRecord
from rig.config import RigConfig
from rig.kinds import rig_kind
from rig.steps import Step

__all__ = ["StepRunner"]

#: Frame ids, unique over the daemon's life (``next`` on a count is atomic).
_FRAME_IDS = itertools.count(1)


class StepRunner:
    """Runs the steps of session ``session`` on ``config``'s rig into ``archive``."""

    def __init__(
        self,
        *,
        session: str,
        config: RigConfig,
        archive: Archive,
        outbox: SessionOutbox,
    ):
        self.session = session
        self.config = config
        self.archive = archive
        self.outbox = outbox
        #: The lamp the previous step left lit for the next one (None: all off).
        self.lit: str | None = None

    def move(self, step: Step, devices: DeviceSet) -> dict:
        """Move to the step's pose and wait until settled; the actuators' positions."""
        actuators = devices.place(step.pose)
        self.outbox.publish("telemetry", {"session": self.session, "step": step.index, **actuators})
        return actuators

    def expose(
        self,
        step: Step,
        devices: DeviceSet,
        actuators: dict,
        started_at: float,
        following: Step | None,
    ) -> tuple[int, tuple[FrameFlag, ...]]:
        """Light, capture, check and commit the step that ``move`` placed; how many
        frames it has, and those flagged (``rig.frame_check``: re-captured or not).

        The lamp stays lit where ``following`` (the next step to run) uses it too.
        """
        if step.kind == "mdf":
            mount = int(step.source.removeprefix("laser"))
            devices.laser(mount, True)
            scan = devices.scan(
                step.cameras,
                tilt_deg=step.tilt_deg,
                frames=step.scan_frames,
                exposure_s=step.exposures_s[0],
            )
            # Logged before the commit: a crash in between repeats the scan and its
            # event; readers take the last "scan" event of a step.
            self.archive.log_event("scan", step=step.index, tilts_deg=scan.tilts_deg)
            frames, flags, extra = scan.frames, scan.flags, {"laser": mount}
        else:
            if self.lit != step.source:
                devices.lamp(step.source, True)
                self.lit = step.source
            frames, flags, actuators = checked_capture(
                step, devices, actuators, redrive=lambda: self.move(step, devices)
            )
            extra = {"lamp": step.source}
        record = self._record(step, actuators, started_at, flags=flags, **extra)
        records = {c: [_as_frame_record(f) for f in fr] for c, fr in frames.items()}
        self.archive.append_step(record, records)
        if step.kind == "mdf":
            devices.laser(extra["laser"], False)
        elif following is None or following.source != step.source:
            devices.lamp(step.source, False)
            self.lit = None
        self._stream(step, frames)
        if flags:
            self.outbox.publish("flagged", flagged_payload(self.session, step, flags))
        return sum(len(f) for f in frames.values()), flags

    def _record(
        self, step: Step, actuators: dict, started_at: float, *, flags, **source
    ) -> StepRecord:
        # the directions where the pose the devices were sent to puts cameras and light
        views, light = rig_kind(self.config).step_directions(self.config, step)
        return StepRecord(
            index=step.index,
            kind=step.kind,
            cameras=step.cameras,
            views_deg=views,
            light_deg=light,
            actuators=actuators,
            exposures_s=step.exposures_s,
            started_at=started_at,
            flags=flags,
            **source,
        )

    def _stream(self, step: Step, frames: dict[str, list[Captured]]) -> None:
        for camera, captured in frames.items():
            for frame in captured:
                header = FrameHeader(
                    frame_id=next(_FRAME_IDS),
                    session=self.session,
                    step=step.index,
                    kind=step.kind,
                    camera=camera,
                    sub=frame.sub,
                    exposure_s=frame.exposure_s,
                    timestamp=frame.timestamp,
                    array=ArraySpec(dtype=frame.image.dtype.name, shape=frame.image.shape),
                    archive=str(self.archive.path),
                )
                self.outbox.stream(header, frame.image)


def _as_frame_record(frame: Captured) -> FrameRecord:
    return FrameRecord(frame.image, frame.sub, frame.exposure_s, frame.timestamp)
