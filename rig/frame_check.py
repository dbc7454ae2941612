"""Is a frame what it was meant to record? The state check every captured frame gets.

A step means each frame to record one state of the rig: the laser sheet at a
planned tilt, exactly the step's lamp lit, the turntable and the arc (or the
Bonn rail) where the step sent them. The devices say what they really did —
the NXT tacho count of the tilt motor, the lamp bank's coils, the Modbus and
Dynamixel position registers — read back before the trigger and after the
frame came back; the camera's own timestamps say whether a frame is new.
``frame_mismatch`` compares them and names every difference, so that the
daemon can flag the frame in the archive, take it again, and say why.

The scan's planned tilts live here too (``scan_tilts_deg``): the session, the
check and the timing model read the same plan.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from rig.archive import FrameFlag, StepRecord
from rig.config import RigConfig

__all__ = [
    "AXIS_TOLERANCE_DEG",
    "FrameState",
    "flag_summary",
    "flags_of",
    "frame_mismatch",
    "scan_tilts_deg",
    "stale_frames",
    "tilt_tolerance_deg",
]

#: How far (deg) a turntable, arc or rail read-back may lie from where the step sent
#: it: a few encoder ticks or steps, well below a degree of view or light direction.
AXIS_TOLERANCE_DEG = 0.1
#: How many steps' reasons ``flag_summary`` quotes.
_REASONS = 10


@dataclass(frozen=True)
class FrameState:
    """The rig's state around one frame: what a step meant, or what a device read back.

    ``tilt_deg``: laser sheet tilt (deg), None where no laser scans.
    ``lamps_on``: the lamps lit, None where not checked (a laser step lights none).
    ``axes``: actuator positions by name (``turntable_deg``, ``arc_deg``, ``rail_deg``).
    """

    tilt_deg: float | None = None
    lamps_on: frozenset[str] | None = None
    axes: Mapping[str, float] = field(default_factory=dict)


def scan_tilts_deg(config: RigConfig, tilt_deg: tuple[float, float], frames: int) -> np.ndarray:
    """The tilt (deg) each of a scan's ``frames`` frames is planned at, (frames,) float64.

    Spread evenly from ``tilt_deg[0]`` to ``[1]``, but never closer than the sheet
    moves in one laser frame period (``sweep_speed_deg_s / frame_rate_hz``): a finer
    step is taken at that spacing, and the frames beyond the end are planned at the end.
    """
    start, end = tilt_deg
    laser = config.laser
    sweep = abs(end - start)
    spacing = max(sweep / max(frames - 1, 1), laser.sweep_speed_deg_s / laser.frame_rate_hz)
    travelled = np.minimum(np.arange(frames) * spacing, sweep)
    return start + np.sign(end - start) * travelled


def tilt_tolerance_deg(config: RigConfig, tilts_deg: Sequence[float]) -> float:
    """How far (deg) a scan frame's tilt read-backs may lie from its planned tilt.

    One planned frame spacing: the sheet moves that far in one laser frame period,
    so a camera that keeps the frame rate sees it within that distance; and never
    less than two tacho counts, the read-back's own resolution.
    """
    tilts = np.asarray(tilts_deg, dtype=np.float64)
    steps = np.abs(np.diff(tilts))
    spacing = float(steps[steps > 0].min()) if np.any(steps > 0) else 0.0
    return max(spacing, 2.0 * config.laser.device.gear_ratio)


def frame_mismatch(
    meant: FrameState,
    readbacks: Sequence[FrameState],
    *,
    tilt_tolerance_deg: float,
    axis_tolerance_deg: float = AXIS_TOLERANCE_DEG,
) -> str | None:
    """Why a frame does not record ``meant``; None when every read-back agrees.

    ``readbacks`` are the devices' reports around the exposure (before the
    trigger, after the frame came back): each state the exposure may have seen
    must match. A field that ``meant`` leaves None (or an axis it does not name)
    is not checked; a read-back that lacks a checked field is not evidence either
    way. The reason names the device, the value read back and the one planned.
    """
    reasons = []
    if meant.tilt_deg is not None:
        tilts = [r.tilt_deg for r in readbacks if r.tilt_deg is not None]
        if any(abs(t - meant.tilt_deg) > tilt_tolerance_deg for t in tilts):
            seen = "…".join(f"{t:.3f}°" for t in tilts)
            reasons.append(
                f"laser tilt read back {seen} around the exposure, planned "
                f"{meant.tilt_deg:.3f}° ± {tilt_tolerance_deg:.3f}°"
            )
    if meant.lamps_on is not None:
        lit = {r.lamps_on for r in readbacks if r.lamps_on is not None}
        wrong = sorted(sorted(s) for s in lit if s != meant.lamps_on)
        if wrong:
            reasons.append(f"lamps read back lit {wrong[0]}, planned {sorted(meant.lamps_on)}")
    for axis, wanted in meant.axes.items():
        got = [r.axes[axis] for r in readbacks if axis in r.axes]
        # a turntable read back at 359.95° is at -0.05°
        off = [g for g in got if abs((g - wanted + 180.0) % 360.0 - 180.0) > axis_tolerance_deg]
        if off:
            reasons.append(
                f"{axis} read back {off[0]:.3f}, planned {wanted:.3f} ± {axis_tolerance_deg}"
            )
    return "; ".join(reasons) or None


def stale_frames(timestamps: Sequence[float]) -> dict[int, str]:
    """Frames (by position) whose camera timestamp is not later than the one before.

    A camera that hands back a buffered or repeated frame gives it the old
    frame's time; such a frame did not see the state it was triggered for.
    """
    stale = {}
    for i in range(1, len(timestamps)):
        if not timestamps[i] > timestamps[i - 1]:
            stale[i] = (
                f"camera timestamp {timestamps[i]:.6f} s is not later than the frame "
                f"before's {timestamps[i - 1]:.6f} s (a stale frame)"
            )
    return stale


def flags_of(steps: Iterable[StepRecord]) -> list[tuple[int, FrameFlag]]:
    """Every frame flag of ``steps`` with its step index, in step order."""
    return [(step.index, flag) for step in steps for flag in step.flags]


def flag_summary(flags: Iterable[tuple[int, FrameFlag]]) -> dict:
    """What ``rig status`` and ``rig process`` report of flagged frames.

    ``frames`` flagged in all, ``recaptured`` (taken again, the archived frame
    matches) and ``left_out`` (still mismatched: processing leaves them out);
    ``steps``: their step indices; ``reasons``: the first reason at each of the
    first ``_REASONS`` such steps (a status reply stays small however many).
    """
    flags = list(flags)
    reasons: dict[str, str] = {}
    for index, flag in flags:
        if len(reasons) < _REASONS or str(index) in reasons:
            reasons.setdefault(str(index), f"{flag.camera} frame {flag.sub}: {flag.reason}")
    return {
        "frames": len(flags),
        "recaptured": sum(flag.recaptured for _, flag in flags),
        "left_out": sum(not flag.recaptured for _, flag in flags),
        "steps": sorted({index for index, _ in flags}),
        "reasons": reasons,
    }
