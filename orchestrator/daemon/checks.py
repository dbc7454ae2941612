"""The state check of a lamp step's frames, and how flagged frames are announced.

A lamp step's frames must record the step's lamp alone, lit, with the axes
where the step's move settled them (the move's read-back, which the drivers
checked against the step's targets on arrival). After the frames came back the
devices' telemetry — the lamp bank's coils, the turntable's Modbus and the
arc's Dynamixel position registers, the Bonn rail's — must still say so, and
each camera's timestamps must rise. A step whose frames fail
is driven again (the axes re-sent, the lamp switched again) and taken again
once; what still fails stays flagged (``rig.archive.FrameFlag``) and processing
leaves it out. Laser steps check their frames in ``orchestrator.daemon.scan``.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence

from orchestrator.daemon.devices import Captured, DeviceSet
from rig.archive import FrameFlag
from rig.frame_check import FrameState, frame_mismatch, stale_frames
from rig.steps import Step

__all__ = ["checked_capture", "flagged_payload"]

Frames = dict[str, list[Captured]]


def checked_capture(
    step: Step,
    devices: DeviceSet,
    actuators: Mapping[str, float],
    redrive: Callable[[], Mapping[str, float]],
) -> tuple[Frames, tuple[FrameFlag, ...], Mapping[str, float]]:
    """Capture ``step``'s frames and check them; once more after ``redrive`` if any fail.

    ``actuators``: the move's settled read-back; ``redrive()`` sends the axes
    again and returns the new read-back. Returns the frames to commit, their
    flags and the actuators' read-back the frames were taken at.
    """
    frames = devices.capture(step.cameras, step.exposures_s)
    reasons = _mismatches(step, actuators, devices.telemetry(), frames)
    if not reasons:
        return frames, (), actuators
    devices.forget_position()
    actuators = redrive()
    devices.lamp(step.source, True)
    frames = devices.capture(step.cameras, step.exposures_s)
    still = _mismatches(step, actuators, devices.telemetry(), frames)
    flags = []
    for key in sorted({*reasons, *still}):
        reason = reasons.get(key, "matched at first")
        if key in still:
            reason = f"{reason}; taken again: {still[key]}"
        flags.append(FrameFlag(*key, reason, recaptured=key not in still))
    return frames, tuple(flags), actuators


def _mismatches(
    step: Step, settled: Mapping[str, float], after: Mapping, frames: Frames
) -> dict[tuple[str, int], str]:
    """Why each frame (by camera and sub) does not record ``step``'s state: its lamp
    alone, and the axes where the move settled (the drivers checked that against the
    step's targets on arrival; here they must not have left it)."""
    meant = FrameState(
        lamps_on=frozenset({step.source}),
        axes={axis: settled[axis] for axis in step.pose.checked_axes if axis in settled},
    )
    readback = FrameState(
        lamps_on=None if "lamps_on" not in after else frozenset(after["lamps_on"]),
        axes={axis: after[axis] for axis in meant.axes if axis in after},
    )
    why = frame_mismatch(meant, [readback], tilt_tolerance_deg=0.0)
    reasons = {}
    for camera, captured in frames.items():
        stale = stale_frames([f.timestamp for f in captured])
        for frame in captured:
            reason = "; ".join(r for r in (why, stale.get(frame.sub)) if r)
            if reason:
                reasons[camera, frame.sub] = reason
    return reasons


def flagged_payload(session: str, step: Step, flags: Sequence[FrameFlag]) -> dict:
    """The ``flagged`` event: a step's frames that did not record its state, and why."""
    return {
        "session": session,
        "step": step.index,
        "kind": step.kind,
        "frames": len(flags),
        "recaptured": sum(f.recaptured for f in flags),
        "reason": flags[0].reason,
    }
