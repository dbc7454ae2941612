"""An axis (the light arc) turned by one or more X-series Dynamixel servos together.

All servos get the same goal (one SYNC_WRITE, so they start together), and
waiting polls them with SYNC_READs on the injected clock. Degrees of the axis
become servo ticks through ``deg_to_ticks`` (ticks per turn, gear ratio, zero
tick of the ``DynamixelServos`` section). The motion profile (velocity,
acceleration) is loaded into the servos from the axis limits unless the
config gives raw values.
"""

from __future__ import annotations

import logging

from drivers.dynamixel._bus import DynamixelBus, describe_hardware_error
from drivers.errors import DeviceError, DeviceFault, DeviceTimeout, MotionStalled
from drivers.registry import register
from rig.clock import Clock
from rig.config import Axis, LightArc
from rig.devices import RAIL_ROLE, DynamixelServos
from rig.errors import KinematicsError

__all__ = ["DynamixelArc", "X", "deg_to_ticks", "ticks_to_deg"]

log = logging.getLogger(__name__)


class X:
    """X-series control-table addresses (ROBOTIS e-manual, e.g. XM430-W350)."""

    MODEL_NUMBER = 0
    OPERATING_MODE = 11
    MAX_POSITION_LIMIT = 48
    MIN_POSITION_LIMIT = 52
    TORQUE_ENABLE = 64
    HARDWARE_ERROR_STATUS = 70
    PROFILE_ACCELERATION = 108
    PROFILE_VELOCITY = 112
    GOAL_POSITION = 116
    MOVING = 122
    PRESENT_POSITION = 132
    VELOCITY_UNIT_RPM = 0.229
    ACCELERATION_UNIT_RPM2 = 214.577
    EXTENDED_RANGE = 1_048_575


def deg_to_ticks(servos: DynamixelServos, deg: float) -> int:
    """Servo goal position (ticks) for an axis angle (deg)."""
    ticks = deg / 360.0 * servos.gear_ratio * servos.ticks_per_rev
    return servos.zero_tick + round(ticks)


def ticks_to_deg(servos: DynamixelServos, ticks: float) -> float:
    """Axis angle (deg) of a servo present position (ticks)."""
    turns = (ticks - servos.zero_tick) / servos.ticks_per_rev
    return turns / servos.gear_ratio * 360.0


_POSITION_MODE, _EXTENDED_MODE = 3, 4
# one SYNC_READ from goal position (116) to present position (132..135)
_STATE_START, _STATE_SIZE = X.GOAL_POSITION, X.PRESENT_POSITION + 4 - X.GOAL_POSITION


class DynamixelArc:
    """Driver of servos turning an axis; satisfies ``drivers.interfaces.Axis``.

    Parameters
    ----------
    servos : DynamixelServos
        Servo ids, port, gearing and raw profile.
    axis : Axis
        Travel limits (deg), speed and acceleration, settle time.
    clock : Clock
        Time for polling and backoff.
    poll_s : float
        Interval between polls while waiting.
    in_position_ticks : int
        How close (ticks) to the goal counts as arrived.
    name : str
        The device's name in errors.
    """

    def __init__(
        self,
        servos: DynamixelServos,
        *,
        axis: Axis,
        clock: Clock,
        poll_s: float = 0.05,
        in_position_ticks: int = 8,
        name: str = "light arc",
    ):
        if poll_s <= 0:
            raise ValueError(f"{name}: poll_s={poll_s} must be > 0")
        self.servos = servos
        self.axis = axis
        self.settle_s = axis.settle_s
        self.name = name
        self.ids = tuple(servos.ids)
        self._clock = clock
        self._poll_s = poll_s
        self._tolerance = in_position_ticks
        self._bus = DynamixelBus(servos, device=name, clock=clock)
        self._tick_range: dict[int, tuple[int, int]] = {}
        self._goal_ticks: int | None = None
        self._target_deg = 0.0

    # -- setup ---------------------------------------------------------------
    def home(self) -> None:
        """``enable``: the servos' encoders are absolute, so there is no homing run."""
        self.enable()

    def enable(self) -> None:
        """Ping each servo, check its mode and errors, load the profile, torque on."""
        for servo_id in self.ids:
            self._bus.ping(servo_id)
            self._tick_range[servo_id] = self._valid_ticks(servo_id)
            bits = self._bus.read(servo_id, X.HARDWARE_ERROR_STATUS, 1, operation="enable")
            if bits:
                raise DeviceFault(
                    self.name,
                    "enable",
                    f"servo {servo_id} reports hardware error 0x{bits:02x} "
                    f"({describe_hardware_error(bits)}); fix the cause, then reboot it",
                )
            velocity, acceleration = self.profile()
            self._bus.write(servo_id, X.PROFILE_VELOCITY, 4, velocity, operation="enable")
            self._bus.write(servo_id, X.PROFILE_ACCELERATION, 4, acceleration, operation="enable")
            self._bus.write(servo_id, X.TORQUE_ENABLE, 1, 1, operation="enable")

    def disable(self) -> None:
        """Torque off on every servo."""
        for servo_id in self.ids:
            self._bus.write(servo_id, X.TORQUE_ENABLE, 1, 0, operation="disable")

    def reboot(self) -> None:
        """Reboot every servo (clears hardware errors); call ``enable`` again after."""
        for servo_id in self.ids:
            self._bus.reboot(servo_id)

    def profile(self) -> tuple[int, int]:
        """Raw (profile velocity, profile acceleration) loaded into the servos."""
        turns_per_deg = self.servos.gear_ratio / 360.0
        velocity = self.servos.profile_velocity or max(
            1, round(self.axis.speed_deg_s * turns_per_deg * 60.0 / X.VELOCITY_UNIT_RPM)
        )
        acceleration = self.servos.profile_acceleration or max(
            1,
            round(self.axis.accel_deg_s2 * turns_per_deg * 3600.0 / X.ACCELERATION_UNIT_RPM2),
        )
        return velocity, acceleration

    # -- motion --------------------------------------------------------------
    def move_to(self, deg: float) -> None:
        """Send every servo the goal for arc angle ``deg`` in one SYNC_WRITE, verified."""
        deg = float(deg)
        axis = self.axis
        if not axis.min_deg <= deg <= axis.max_deg:
            raise KinematicsError(
                f"{self.name}: move_to {deg}° is outside the axis range "
                f"[{axis.min_deg}°, {axis.max_deg}°]"
            )
        if not self._tick_range:
            raise DeviceError(self.name, "move_to", "servos not enabled; call enable() first")
        goal = deg_to_ticks(self.servos, deg)
        for servo_id, (low, high) in self._tick_range.items():
            if not low <= goal <= high:
                raise DeviceError(
                    self.name,
                    "move_to",
                    f"{deg}° is goal tick {goal}, outside servo {servo_id}'s range "
                    f"[{low}, {high}]; check light_arc.device.zero_tick and the operating mode",
                )
        op = f"move_to {deg:.2f}°"
        self._bus.sync_write(X.GOAL_POSITION, 4, dict.fromkeys(self.ids, goal), operation=op)
        # SYNC_WRITE has no reply: read the goals back so a lost packet is not a "stall".
        goals = self._goals(op)
        missed = [i for i, g in goals.items() if g != goal]
        if missed:
            self._bus.sync_write(X.GOAL_POSITION, 4, {i: goal for i in missed}, operation=op)
            goals = self._goals(op)
            if any(goals[i] != goal for i in missed):
                raise DeviceError(
                    self.name,
                    op,
                    f"servos {missed} did not take goal tick {goal} (read back {goals})",
                )
        self._goal_ticks = goal
        self._target_deg = deg

    def position(self) -> float:
        """The arc angle (deg): mean of the servos' present positions."""
        state = self._state("position")
        ticks = [present for _, _, present in state.values()]
        return ticks_to_deg(self.servos, sum(ticks) / len(ticks))

    def wait_until_settled(self, timeout_s: float | None = None) -> float:
        """Poll until every servo stops at the goal; return the arc angle (deg).

        Raises
        ------
        DeviceFault
            A servo reports a hardware error (names servo and error bits).
        MotionStalled
            A servo stopped short of the goal on two polls in a row.
        DeviceTimeout
            Still moving after ``timeout_s`` (default: twice the move time + 1 s).
        """
        if self._goal_ticks is None:
            return self.position()
        goal = self._goal_ticks
        target_deg = self._target_deg
        op = f"move_to {target_deg:.2f}°"
        if timeout_s is None:
            timeout_s = 2.0 * float(self.axis.move_time_s(target_deg - self.position())) + 1.0
        deadline = self._clock.now() + timeout_s
        idle_polls = 0
        while True:
            errors = self._bus.sync_read(X.HARDWARE_ERROR_STATUS, 1, self.ids, operation=op)
            for servo_id, raw in errors.items():
                if raw[0]:
                    raise DeviceFault(
                        self.name,
                        op,
                        f"servo {servo_id} reports hardware error 0x{raw[0]:02x} "
                        f"({describe_hardware_error(raw[0])}) at {self.position():.2f}°",
                    )
            state = self._state(op)
            moving = any(m for _, m, _ in state.values())
            arrived = all(
                abs(present - goal) <= self._tolerance for _, _, present in state.values()
            )
            where = ticks_to_deg(self.servos, sum(p for _, _, p in state.values()) / len(state))
            if arrived and not moving:
                return where
            idle_polls = 0 if moving else idle_polls + 1
            if idle_polls >= 2:
                short = {
                    i: round(ticks_to_deg(self.servos, p), 2) for i, (_, _, p) in state.items()
                }
                raise MotionStalled(
                    self.name,
                    op,
                    f"stopped at {where:.2f}° short of the target {target_deg:.2f}° "
                    f"(servo angles {short}); check for a jam or an overload",
                )
            if self._clock.now() >= deadline:
                raise DeviceTimeout(
                    self.name,
                    op,
                    f"still moving at {where:.2f}° towards {target_deg:.2f}° "
                    f"after {timeout_s:.1f} s",
                )
            self._clock.sleep(self._poll_s)

    def stop(self) -> None:
        """Hold every servo where it is now (goal = present position)."""
        state = self._state("stop")
        here = {servo_id: present for servo_id, (_, _, present) in state.items()}
        self._bus.sync_write(X.GOAL_POSITION, 4, here, operation="stop")
        self._goal_ticks = None

    def close(self) -> None:
        """Close the bus; idempotent. Torque stays as it is (the arc holds)."""
        self._bus.close()

    # -- internals -----------------------------------------------------------
    def _valid_ticks(self, servo_id: int) -> tuple[int, int]:
        mode = self._bus.read(servo_id, X.OPERATING_MODE, 1, operation="enable")
        if mode == _EXTENDED_MODE:
            return -X.EXTENDED_RANGE, X.EXTENDED_RANGE
        if mode == _POSITION_MODE:
            low = self._bus.read(servo_id, X.MIN_POSITION_LIMIT, 4, operation="enable")
            high = self._bus.read(servo_id, X.MAX_POSITION_LIMIT, 4, operation="enable")
            return low, high
        raise DeviceError(
            self.name,
            "enable",
            f"servo {servo_id} is in operating mode {mode}; the arc needs 3 (position) "
            f"or 4 (extended position): set it with the Dynamixel Wizard",
        )

    def _goals(self, operation: str) -> dict[int, int]:
        return {i: goal for i, (goal, _, _) in self._state(operation).items()}

    def _state(self, operation: str) -> dict[int, tuple[int, bool, int]]:
        """Per servo: (goal ticks, moving, present ticks) from one SYNC_READ."""
        raw = self._bus.sync_read(_STATE_START, _STATE_SIZE, self.ids, operation=operation)
        out = {}
        for servo_id, data in raw.items():
            goal = int.from_bytes(data[0:4], "little", signed=True)
            moving = bool(data[X.MOVING - _STATE_START])
            at = X.PRESENT_POSITION - _STATE_START
            present = int.from_bytes(data[at : at + 4], "little", signed=True)
            out[servo_id] = (goal, moving, present)
        return out


@register("light_arc", "dynamixel")
@register(RAIL_ROLE, "dynamixel")
def open_light_arc(section: LightArc, *, clock: Clock) -> DynamixelArc:
    """The light arc of a rig config (or the Bonn lab's rail), on its Dynamixel servos."""
    return DynamixelArc(section.device, axis=section.axis, clock=clock)
