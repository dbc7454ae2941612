"""The rig's timing model: how long a step's move, settle, lamp and capture take.

One model, used wherever time is predicted or spent on purpose: the plan
estimate (:func:`rig.schedule.estimate`), the simulator's capture timing
(:meth:`sim.Simulator.capture_timing`) and the daemon benchmark's modelled rig.

- Motion (:func:`motion_s`, a Wang rig's; each rig kind has its own,
  ``RigKind.motion_s``): turntable and arc move at once, each on its trapezoidal
  profile (:meth:`rig.config.Axis.move_time_s`); the step waits for the slower,
  then for the longer settle time of the axes that moved.
- Lamp: the bank waits its warm-up after each switch: on (the light settles)
  and off (the sensors confirm it dark), so twice per lamp step.
- Capture: the cameras of a step fire together, so each exposure costs its
  duration plus the slowest camera's readout (once, not once per camera);
  readout scales with the fraction of the sensor read (``scale``).
- Laser scan: the frames at the scan frame rate, or the sheet's sweep if that
  is slower, then the sweep back to the start.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING

import numpy as np

from rig.config import RigConfig

if TYPE_CHECKING:
    from rig.steps import Step

__all__ = ["StepTiming", "motion_s", "readout_s", "scan_s", "shots_s", "step_timing"]

_MOVED_DEG = 1e-9  # a smaller change of an axis is no move (and needs no settling)


@dataclass(frozen=True)
class StepTiming:
    """Durations (s) of the phases of one step (or one capture)."""

    move_s: float
    settle_s: float
    lamp_s: float
    capture_s: float

    @property
    def total_s(self) -> float:
        return self.move_s + self.settle_s + self.lamp_s + self.capture_s

    def as_dict(self) -> dict:
        return {**asdict(self), "total_s": self.total_s}


def motion_s(config: RigConfig, start, target) -> tuple[np.ndarray, np.ndarray]:
    """Move and settle time (s) from ``start`` to ``target`` = (turntable_deg, arc_deg).

    Both may be arrays (broadcast): the planner prices many targets at once.
    """
    tt, arc = config.turntable.axis, config.light_arc.axis
    d_tt = np.abs(np.asarray(target[0], dtype=np.float64) - start[0])
    d_arc = np.abs(np.asarray(target[1], dtype=np.float64) - start[1])
    move = np.maximum(tt.move_time_s(d_tt), arc.move_time_s(d_arc))
    settle = np.maximum(
        np.where(d_tt > _MOVED_DEG, tt.settle_s, 0.0),
        np.where(d_arc > _MOVED_DEG, arc.settle_s, 0.0),
    )
    return move, settle


def readout_s(config: RigConfig, cameras: Sequence[str], *, scale: float = 1.0) -> float:
    """Readout (s) of ``cameras`` fired together: the slowest, for ``scale`` of the rows."""
    return max(config.camera(c).readout_s for c in cameras) * scale


def shots_s(
    config: RigConfig, cameras: Sequence[str], exposures_s: Sequence[float], *, scale: float = 1.0
) -> float:
    """Time (s) for ``cameras`` to take one frame per exposure, all firing together."""
    readout = readout_s(config, cameras, scale=scale)
    return float(sum(e + readout for e in exposures_s))


def scan_s(config: RigConfig, frames: int, sweep_deg: float) -> float:
    """Time (s) of a laser scan of ``frames`` frames over ``sweep_deg``, and the sweep back."""
    sweep = abs(sweep_deg) / config.laser.sweep_speed_deg_s
    return max(frames / config.laser.frame_rate_hz, sweep) + sweep


def step_timing(
    config: RigConfig, step: Step, start, *, scale: float = 1.0, motion=motion_s
) -> StepTiming:
    """Timing of ``step`` with the actuators at the pose ``start``; ``motion`` is the rig
    kind's move-time model (``RigKind.motion_s``)."""
    move, settle = motion(config, start, step.pose)
    if step.kind == "mdf":
        lamp = 0.0
        capture = scan_s(config, step.scan_frames, step.tilt_deg[1] - step.tilt_deg[0])
    else:
        lamp = 2 * config.lamp_bank.warmup_s
        capture = shots_s(config, step.cameras, step.exposures_s, scale=scale)
    return StepTiming(float(move), float(settle), lamp, capture)
