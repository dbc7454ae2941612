"""One measurement session: the compiled steps run against the devices, committed to the archive.

A step is idempotent: move (both axes) → settle → lamp or laser → trigger the
cameras → read → commit (one atomic archive append) → lamp off → stream the
frames to the workers (``step.StepRunner``). A lamp the next step uses too stays
lit (a fixed lamp is lit once for all its steps, as a lab keeps it); a fault
switches everything off. Lamps and cameras act only after ``move`` returned,
i.e. after the axes settled. Steps already in the archive
are skipped, which is how a crashed session resumes: ``Session.resume_from``
recompiles the stored plan on the stored rig config and goes on after the last
commit. ``progress.Progress`` keeps the counts and the ETA.

Control (pause, resume, abort) arrives from other threads through the shared
``StateMachine``; the session acts on it between steps. A ``DeviceError``
that survived the driver's retries pauses the session with the device and
step named (``on_fault="pause"``), and ``resume`` retries that step; with
``on_fault="fail"`` the session fails with the same reason.
"""

from __future__ import annotations

import contextlib
import logging
import threading
import uuid
from collections.abc import Callable
from pathlib import Path
from typing import Literal

from drivers.errors import DeviceError
from orchestrator.daemon.admission import (
    SessionError,
    check_archive_place,
    check_not_finished,
    check_plan_size,
    check_same_rig,
)
from orchestrator.daemon.devices import DeviceSet
from orchestrator.daemon.progress import Progress
from orchestrator.daemon.state import IllegalTransition, SessionEvent, SessionState, StateMachine
from orchestrator.daemon.step import StepRunner
from orchestrator.daemon.stream import SessionOutbox
from rig.archive import Archive, ArchiveError, ArchiveFull, FrameFormat
from rig.calfile import load_calibration
from rig.clock import Clock
from rig.config import RigConfig
from rig.errors import RigError
from rig.frame_check import flags_of
from rig.material import copy_flat_field
from rig.plan import Plan, parse_plan
from rig.schedule import compile_plan
from rig.steps import Schedule, Step

__all__ = ["DeviceFactory", "Session", "SessionError", "frame_formats"]

log = logging.getLogger(__name__)

#: ``factory(config, clock=, scale=, laser=)`` → an open device set.
DeviceFactory = Callable[..., DeviceSet]


def frame_formats(config: RigConfig, *, scale: float) -> dict[str, FrameFormat]:
    """The archive's frame format of every camera at a resolution ``scale`` (the plan's)."""
    formats = {}
    for cam in config.camera_arc.cameras:
        h, w = max(1, round(cam.height * scale)), max(1, round(cam.width * scale))
        dtype = "uint8" if cam.bit_depth == 8 else "uint16"
        formats[cam.id] = FrameFormat(h, w, cam.channels, dtype)
    return formats


class Session:
    """Runs one plan; ``run()`` is the session thread's body.

    Create with ``Session.start_new`` (new archive) or ``Session.resume_from``.
    """

    def __init__(
        self,
        *,
        plan: Plan,
        config: RigConfig,
        schedule: Schedule,
        archive: Archive,
        devices: DeviceFactory,
        clock: Clock,
        machine: StateMachine,
        outbox: SessionOutbox,
        on_fault: Literal["pause", "fail"] = "pause",
        drain_timeout_s: float = 30.0,
    ):
        self.id = uuid.uuid4().hex[:12]
        self.plan = plan
        self.config = config
        self.archive = archive
        self.schedule = schedule
        self._check_archive_matches()
        self._devices_factory = devices
        self.clock = clock
        self.machine = machine
        self.outbox = outbox
        self.on_fault = on_fault
        self.drain_timeout_s = drain_timeout_s
        self._changed = threading.Condition()
        self._progress = Progress(
            schedule,
            committed=len(archive.committed_steps()),
            frames=len(archive.frame_table()),
            flags=flags_of(archive.step_table()),
        )
        self._steps = StepRunner(session=self.id, config=config, archive=archive, outbox=outbox)

    # -- creating ---------------------------------------------------------------------------

    @classmethod
    def start_new(
        cls, plan_toml: str, *, source: str, archive_path, config: RigConfig, **kw
    ) -> Session:
        """A session of a new plan writing a new archive (which must not exist).

        The plan is validated and compiled, and the archive's place checked, before the
        archive is created: a plan that fails leaves nothing behind. ``archive_path``
        None: the plan's ``output.archive``.
        """
        plan = parse_plan(plan_toml, source=source)
        if archive_path is None:
            target, field = plan.archive_path(), "args.plan_toml"
        else:
            target, field = Path(archive_path), "args.archive"
        check_archive_place(target, field)
        check_plan_size(plan, source)
        schedule = compile_plan(plan, config)
        calibration = _calibration_of(config)
        archive = Archive.create(
            target,
            plan=plan.model_dump(mode="json"),
            plan_toml=plan_toml,
            rig_config=config.model_dump(mode="json"),
            cameras=frame_formats(config, scale=plan.resolution.scale),
            calibration=calibration,
        )
        try:
            _copy_flat_field(config, calibration, archive)
            return cls(plan=plan, config=config, schedule=schedule, archive=archive, **kw)
        except BaseException:
            archive.close()
            raise

    @classmethod
    def resume_from(cls, archive_path, *, config: RigConfig, **kw) -> Session:
        """Continue the session stored in ``archive_path`` after its last committed step,
        with the devices of ``config`` (the daemon's: where they are connected now).

        ``config`` must describe the rig the archive recorded: connections (ports,
        addresses) may differ, geometry may not.
        """
        archive = Archive.open(archive_path, mode="a")
        try:
            if archive.plan_toml is None:
                raise SessionError(f"{archive_path}: the archive keeps no plan text to resume")
            check_not_finished(archive)
            recorded = RigConfig.model_validate(archive.rig_config)
            check_same_rig(recorded, config, source=str(archive_path))
            plan = parse_plan(archive.plan_toml, source=f"{archive_path} (stored plan)")
            schedule = compile_plan(plan, config)
            return cls(plan=plan, config=config, schedule=schedule, archive=archive, **kw)
        except BaseException:
            archive.close()
            raise

    def _check_archive_matches(self) -> None:
        steps = {s.index: s for s in self.schedule.steps}
        for record in self.archive.step_table():
            step = steps.get(record.index)
            if step is None or (step.kind, step.cameras) != (record.kind, record.cameras):
                raise SessionError(
                    f"{self.archive.path}: committed step {record.index} ({record.kind}) does not "
                    "match the recompiled plan; this archive cannot be resumed by this version"
                )

    # -- control from other threads ---------------------------------------------------------

    def notify(self) -> None:
        """Wake the session thread (the daemon calls it after every state change)."""
        with self._changed:
            self._changed.notify_all()

    def status(self) -> dict:
        """A snapshot of the progress (thread-safe)."""
        return {
            "session": self.id,
            "sample": self.plan.sample.name,
            "archive": str(self.archive.path),
            "steps": len(self.schedule.steps),
            **self._progress.snapshot(),
            "estimate_s": self.schedule.estimate.total_s,
        }

    # -- the session thread -----------------------------------------------------------------

    def run(self) -> None:
        """Home, run every uncommitted step, finish; ends in done, aborted or failed.

        The final transition comes after devices and archive are closed, so a
        client that sees ``done`` or ``failed`` can open the archive at once.
        """
        devices = None
        reason = None
        try:
            committed = set(self.archive.committed_steps())
            self._log("session", action="start", session=self.id, committed=len(committed))
            has_laser = any(s.kind == "mdf" for s in self.schedule.steps)
            devices = self._devices_factory(
                self.config, clock=self.clock, scale=self.plan.resolution.scale, laser=has_laser
            )
            devices.home(laser=has_laser)
            self._fire_or_abort(SessionEvent.HOMED)
            self._progress.started(self.clock.now())
            pending = [step for step in self.schedule.steps if step.index not in committed]
            for step, following in zip(pending, [*pending[1:], None], strict=True):
                self._run_with_faults(step, devices, following)
            self._fire_when_running(SessionEvent.STEPS_DONE)
            self._finish(devices)
        except _Aborted:
            log.info("session %s aborted", self.id)
        except Exception as err:  # the session fails with the reason; the daemon goes on
            if isinstance(err, RigError):  # named and explained: the message is the whole story
                log.error("session %s failed: %s", self.id, err)
            else:
                log.exception("session %s failed", self.id)
            reason = f"{type(err).__name__}: {err}"
            self._log("session", action="failed", session=self.id, reason=reason)
        try:
            self._close(devices)
        except ArchiveFull as err:  # after the last commit: nothing is lost, it ends as it was
            log.warning("session %s: closing: %s", self.id, err)
            fault = {"device": "archive", "operation": "close", "detail": str(err)}
            self._progress.set_fault(fault)
            self.outbox.publish("log", {"kind": "fault", **fault})
        except Exception as err:  # closing failed: the session fails, the daemon goes on
            log.exception("session %s: closing failed", self.id)
            reason = reason or f"closing: {type(err).__name__}: {err}"
        if reason is not None:
            self._fail(reason)
        elif self.machine.state == SessionState.FINISHING:
            self._fire(SessionEvent.FINISHED)

    def _run_with_faults(
        self, step: Step, devices: DeviceSet, following: Step | None
    ) -> None:
        while True:
            self._wait_runnable()
            try:
                self._run_step(step, devices, following)
                return
            except DeviceError as err:
                fault = {"device": err.device, "operation": err.operation, "detail": err.detail}
                if self.on_fault == "fail":
                    self._switch_off(devices)
                    raise
            except ArchiveFull as err:  # pauses whatever on_fault says: free space, then resume
                fault = {"device": "archive", "operation": "append", "detail": str(err)}
            fault.update(step=step.index, step_kind=step.kind)
            self._switch_off(devices)
            self._progress.set_fault(fault)
            self._log("fault", **fault)
            # Already paused or aborted by the user: the fault is recorded all the same.
            with contextlib.suppress(IllegalTransition):
                self.machine.fire(SessionEvent.FAULT, **fault)

    def _wait_runnable(self) -> None:
        """Return when running; raise ``_Aborted`` when the session was aborted."""
        with self._changed:
            while True:
                state = self.machine.state
                if state == SessionState.RUNNING:
                    break
                if state != SessionState.PAUSED:
                    raise _Aborted
                self._changed.wait()
        self._progress.set_fault(None)

    def _fire_when_running(self, event: SessionEvent) -> None:
        while True:
            self._wait_runnable()
            try:
                self._fire(event)
                return
            except IllegalTransition:
                continue  # paused in between: wait again

    def _run_step(
        self, step: Step, devices: DeviceSet, following: Step | None
    ) -> None:
        self._progress.at_step(step.index)
        started_at = self.clock.now()
        actuators = self._steps.move(step, devices)
        if self.machine.state == SessionState.ABORTED:  # the move took long: light nothing
            raise _Aborted
        n_frames, flags = self._steps.expose(step, devices, actuators, started_at, following)
        payload = self._progress.step_done(step, n_frames, self.clock.now(), flags=flags)
        self.outbox.publish("progress", {"session": self.id, **payload})

    def _finish(self, devices: DeviceSet) -> None:
        devices.all_off()
        stored = self.outbox.drain(self.id, self.drain_timeout_s)
        self._log("session", action="finished", session=self.id, processed=stored)

    # -- endings ----------------------------------------------------------------------------

    def _fire(self, event: SessionEvent, **detail) -> None:
        self.machine.fire(event, session=self.id, **detail)

    def _fire_or_abort(self, event: SessionEvent) -> None:
        try:
            self._fire(event)
        except IllegalTransition:
            if self.machine.state == SessionState.ABORTED:
                raise _Aborted from None
            raise

    def _fail(self, reason: str) -> None:
        self._progress.set_reason(reason)
        try:
            self._fire(SessionEvent.FAIL, reason=reason)
        except IllegalTransition:
            log.warning("session %s: %s (state %s)", self.id, reason, self.machine.state)

    def _switch_off(self, devices: DeviceSet) -> None:
        self._steps.lit = None
        try:
            devices.all_off()
        except DeviceError as err:
            log.warning("session %s: switching off after a fault: %s", self.id, err)

    def _log(self, kind: str, **payload) -> None:
        try:
            self.archive.log_event(kind, **payload)
        except ArchiveError as err:  # a broken or closed archive must not hide the event
            log.warning("session %s: could not log %s: %s", self.id, kind, err)
        self.outbox.publish("log", {"kind": kind, **payload})

    def _close(self, devices: DeviceSet | None) -> None:
        try:
            if devices is not None:
                self._switch_off(devices)
                devices.close()
        finally:
            self.archive.close()


class _Aborted(Exception):
    """The state machine left the running/paused states from outside."""


def _copy_flat_field(config: RigConfig, calibration: dict | None, archive: Archive) -> None:
    """The lamps' flat fields the calibration names go into the archive with it."""
    name = (calibration or {}).get("lamps_flat_field")
    if name is not None:
        copy_flat_field(config.calibration, name, archive.path)


def _calibration_of(config: RigConfig) -> dict | None:
    """The calibration file the rig config names, validated, for the archive."""
    if config.calibration is None:
        return None
    return load_calibration(config.calibration).model_dump(mode="json", exclude_none=True)
