"""The one world state of the simulated rig.

The device peers change it (a Modbus write moves the turntable, a Dynamixel
goal moves the light arc, an NXT output command tilts the laser) and the camera
server renders from it, so the camera sees exactly what the motors did. Motion
takes time: each axis follows the trapezoidal profile of its rig-config limits
on the injected clock (the ``motion_timing`` effect), and a peer can inject a
stall that stops the axis short of its target. In the Bonn lab the plate's
orientation is where the arm's controller peer holds it (its joints, through
the arm's kinematics) and the rail is one more axis.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from rig.bonn import plate_rotation
from rig.clock import Clock
from rig.config import Axis, RigConfig
from rig.devices import RAIL_ROLE

__all__ = ["AxisMotion", "World", "WorldSnapshot"]


@dataclass
class AxisMotion:
    """One rotary axis moving along a trapezoidal profile."""

    limits: Axis
    start_deg: float = 0.0
    target_deg: float = 0.0
    t_start: float = 0.0
    stall_fraction: float | None = None  # stop at this fraction of the move

    def _end_deg(self) -> float:
        if self.stall_fraction is None:
            return self.target_deg
        return self.start_deg + self.stall_fraction * (self.target_deg - self.start_deg)

    def position(self, t: float) -> float:
        """Position at time ``t`` (deg)."""
        end = self._end_deg()
        delta = end - self.start_deg
        duration = float(self.limits.move_time_s(delta))
        if duration <= 0 or t >= self.t_start + duration:
            return end
        tau = max(0.0, t - self.t_start)
        v, a = self.limits.speed_deg_s, self.limits.accel_deg_s2
        d = abs(delta)
        t_ramp = min(v / a, duration / 2)
        v_peak = a * t_ramp
        if tau < t_ramp:
            s = 0.5 * a * tau * tau
        elif tau < duration - t_ramp:
            s = 0.5 * a * t_ramp * t_ramp + v_peak * (tau - t_ramp)
        else:
            s = d - 0.5 * a * (duration - tau) ** 2
        return self.start_deg + np.sign(delta) * min(s, d)

    def is_moving(self, t: float) -> bool:
        delta = self._end_deg() - self.start_deg
        return t < self.t_start + float(self.limits.move_time_s(delta))

    def command(self, target_deg: float, t: float) -> None:
        self.start_deg = self.position(t)
        self.target_deg = float(target_deg)
        self.t_start = t


@dataclass(frozen=True)
class WorldSnapshot:
    """What the cameras see at one instant."""

    t: float
    turntable_deg: float
    arc_deg: float
    lamps_on: frozenset[str]
    laser_on: bool
    laser_tilt_deg: float
    laser_mount: int
    rail_deg: float = 0.0  # the Bonn lab's camera rail
    # the Bonn lab's plate orientation (sample → lab, row-major 3×3) where the arm holds it
    sample_rotation: tuple[float, ...] | None = None

    def plate_rotation(self) -> np.ndarray:
        """(3, 3) the plate's orientation, sample → lab (identity where no arm holds it)."""
        if self.sample_rotation is None:
            return np.eye(3)
        return np.array(self.sample_rotation, dtype=np.float64).reshape(3, 3)


@dataclass
class World:
    """Shared, thread-safe state of the simulated rig."""

    config: RigConfig
    clock: Clock
    turntable: AxisMotion = field(init=False)
    arc: AxisMotion = field(init=False)
    laser_tilt: AxisMotion = field(init=False)
    rail: AxisMotion | None = field(init=False)  # the Bonn lab's camera rail
    lamps_on: set[str] = field(default_factory=set)
    dead_lamps: set[str] = field(default_factory=set)  # injected: switched on, stays dark
    laser_on: bool = False
    laser_mount: int = 0
    # the Bonn lab's arm: its joints (rad) now, from its controller peer
    arm_joints: Callable[[], np.ndarray] | None = None
    _lock: threading.Lock = field(default_factory=threading.Lock, repr=False)

    def __post_init__(self) -> None:
        self.turntable = AxisMotion(self.config.turntable.axis)
        self.arc = AxisMotion(self.config.light_arc.axis)
        roles = self.config.device_roles
        rail = self.config.device_section(RAIL_ROLE).axis if RAIL_ROLE in roles else None
        self.rail = AxisMotion(rail) if rail is not None else None
        sweep = self.config.laser
        self.laser_tilt = AxisMotion(
            Axis(
                speed_deg_s=sweep.sweep_speed_deg_s,
                accel_deg_s2=sweep.sweep_speed_deg_s * 100,
                settle_s=0.0,
                min_deg=-90.0,
                max_deg=90.0,
            )
        )

    def axis(self, name: str) -> AxisMotion:
        axes = {"turntable": self.turntable, "arc": self.arc, "laser_tilt": self.laser_tilt}
        if self.rail is not None:
            axes["rail"] = self.rail
        try:
            return axes[name]
        except KeyError:
            raise KeyError(f"unknown axis {name!r}; valid are {sorted(axes)}") from None

    def move(self, axis: str, target_deg: float) -> None:
        with self._lock:
            self.axis(axis).command(target_deg, self.clock.now())

    def position(self, axis: str) -> float:
        with self._lock:
            return self.axis(axis).position(self.clock.now())

    def is_moving(self, axis: str) -> bool:
        with self._lock:
            return self.axis(axis).is_moving(self.clock.now())

    def set_lamp(self, lamp_id: str, on: bool) -> None:
        self.config.lamp(lamp_id)  # validates the id
        with self._lock:
            (self.lamps_on.add if on else self.lamps_on.discard)(lamp_id)

    def lamps_switched_on(self) -> frozenset[str]:
        """The lamps whose switch is on (a dead lamp included: it is on, but dark)."""
        with self._lock:
            return frozenset(self.lamps_on)

    def set_diode(self, mount: int, on: bool) -> None:
        """Mount ``mount``'s diode switched: on lights its sheet; off darkens the
        laser only if that mount's sheet was the lit one."""
        with self._lock:
            if on:
                self.laser_on, self.laser_mount = True, mount
            elif self.laser_mount == mount:
                self.laser_on = False

    def snapshot(self) -> WorldSnapshot:
        joints = self.arm_joints() if self.arm_joints is not None else None
        rotation = None if joints is None else plate_rotation(self.config, joints)
        with self._lock:
            t = self.clock.now()
            return WorldSnapshot(
                t=t,
                turntable_deg=self.turntable.position(t),
                arc_deg=self.arc.position(t),
                lamps_on=frozenset(self.lamps_on - self.dead_lamps),
                laser_on=self.laser_on,
                laser_tilt_deg=self.laser_tilt.position(t),
                laser_mount=self.laser_mount,
                rail_deg=self.rail.position(t) if self.rail is not None else 0.0,
                sample_rotation=None if rotation is None else tuple(rotation.ravel().tolist()),
            )
