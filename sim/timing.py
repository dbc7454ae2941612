"""How long a capture takes: move, settle, expose, read out (``motion_timing``).

The axes follow the trapezoidal profiles of their rig-config limits
(:meth:`rig.config.Axis.move_time_s`, the same model :class:`sim.world.World`
moves with); turntable and arc move in parallel, then the slower settles.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

from rig.config import RigConfig
from sim.world import WorldSnapshot

__all__ = ["CaptureTiming", "capture_timing"]


@dataclass(frozen=True)
class CaptureTiming:
    """Durations (s) of the phases of one capture."""

    move_s: float
    settle_s: float
    exposure_s: float
    readout_s: float

    @property
    def total_s(self) -> float:
        return self.move_s + self.settle_s + self.exposure_s + self.readout_s

    def as_dict(self) -> dict:
        return {**asdict(self), "total_s": self.total_s}


def capture_timing(
    rig: RigConfig,
    camera_id: str,
    start: WorldSnapshot,
    *,
    turntable_deg: float,
    arc_deg: float,
    exposure_s: float,
) -> CaptureTiming:
    """Timing of moving from ``start`` to the target positions and capturing."""
    tt, arc = rig.turntable.axis, rig.light_arc.axis
    moves = [
        (float(tt.move_time_s(turntable_deg - start.turntable_deg)), tt.settle_s),
        (float(arc.move_time_s(arc_deg - start.arc_deg)), arc.settle_s),
    ]
    moving = [(t, s) for t, s in moves if t > 0]
    return CaptureTiming(
        move_s=max((t for t, _ in moving), default=0.0),
        settle_s=max((s for _, s in moving), default=0.0),
        exposure_s=exposure_s,
        readout_s=rig.camera(camera_id).readout_s,
    )
