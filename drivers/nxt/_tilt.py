"""The laser sheet's tilt: an NXT motor behind a gearbox, as an ``Axis``.

Motor ``unit.motor_port`` turns the sheet through a gearbox of
``unit.gear_ratio`` degrees of tilt per motor degree. The brick has no
absolute encoder: the rotation count (RESETMOTORPOSITION, absolute) is zeroed
with the sheet at tilt 0 (``zero``), and every tilt is read back from it. A
move is a SETOUTPUTSTATE with a tacho limit of the remaining motor degrees,
so re-sending it after a lost reply still ends at the same absolute tilt.
"""

from __future__ import annotations

from drivers.errors import DeviceError, DeviceTimeout, MotionStalled
from drivers.nxt._brick import NxtBrick
from drivers.nxt._telegram import MOTOR_PORTS, OutputMode, RegulationMode, RunState
from drivers.retry import with_retries
from rig.clock import Clock
from rig.devices import NxtLaserUnit

__all__ = ["NxtTilt"]

_MOVE = OutputMode.MOTORON | OutputMode.BRAKE | OutputMode.REGULATED


class NxtTilt:
    """The tilt axis of one laser unit; satisfies ``drivers.interfaces.Axis``.

    Parameters
    ----------
    brick : the unit's open ``NxtBrick`` (the unit closes it, not the axis).
    unit : the laser's device section (motor port, gearing, power, stall time).
    limit_deg : mechanical tilt range, ±limit (deg).
    speed_deg_s : the tilt speed the motor power gives; bounds every wait.
    clock : injected time for polling, stall detection and the overall timeout.
    poll_s : interval between GETOUTPUTSTATE polls while waiting for a move.
    tolerance_counts : how far (motor degrees) a finished move may end from its
        target (a braked NXT motor overshoots a few degrees) before it counts
        as stopped short.
    """

    settle_s = 0.0  # the sheet is light: nothing rings after a stop

    def __init__(
        self,
        brick: NxtBrick,
        unit: NxtLaserUnit,
        *,
        limit_deg: float,
        speed_deg_s: float,
        clock: Clock,
        poll_s: float = 0.05,
        tolerance_counts: int = 5,
    ):
        self.brick = brick
        self.unit = unit
        self.limit_deg = limit_deg
        self.speed_deg_s = speed_deg_s
        self.clock = clock
        self.poll_s = poll_s
        self.tolerance_counts = tolerance_counts
        self.name = brick.device
        self._motor = MOTOR_PORTS[unit.motor_port]
        self._target_deg: float | None = None

    def zero(self) -> None:
        """Declare the present sheet position tilt 0 (reset the absolute rotation count)."""
        self.brick.reset_motor_position(self._motor, relative=False)

    def home(self) -> None:
        """Tilt the sheet back to 0 (the rotation count's zero) and wait."""
        self.move_to(0.0)
        self.wait_until_settled()

    def position(self) -> float:
        """The sheet's tilt now, from the motor's rotation count (deg)."""
        return self.brick.get_output_state(self._motor).rotation_count * self.unit.gear_ratio

    def move_to(self, deg: float) -> None:
        """Start turning the sheet to ``deg`` and return at once."""
        deg = float(deg)
        if not -self.limit_deg <= deg <= self.limit_deg:
            raise DeviceError(
                self.name,
                f"tilt to {deg}°",
                f"the target is outside the unit's tilt range ±{self.limit_deg}° "
                "(laser.tilt_limit_deg)",
            )
        target_counts = self._counts(deg)

        def attempt() -> None:
            # Re-read the position on every try: a lost reply to a move that did
            # start must not add its distance twice.
            now = self.brick.get_output_state(self._motor, retried=False).rotation_count
            delta = target_counts - now
            if delta == 0:
                return
            power = self.unit.motor_power if delta > 0 else -self.unit.motor_power
            self.brick.set_output_state(
                self._motor,
                power=power,
                mode=_MOVE,
                regulation=RegulationMode.MOTOR_SPEED,
                run_state=RunState.RUNNING,
                tacho_limit=abs(delta),
                retried=False,
            )

        with_retries(
            attempt,
            retry=self.brick.retry,
            clock=self.clock,
            device=self.name,
            operation=f"tilt to {deg}°",
        )
        self._target_deg = deg

    def wait_until_settled(self, timeout_s: float | None = None) -> float:
        """Wait until the motor stops at the target; return the tilt reached (deg).

        ``MotionStalled`` (after braking the motor) when the rotation count has
        not changed for ``unit.stall_timeout_s`` while the brick still runs it;
        ``DeviceTimeout`` (after braking) when the move is still running after
        ``timeout_s`` (default: twice the move at ``speed_deg_s`` plus 1 s).
        """
        target_deg = self._target_deg
        if target_deg is None:
            return self.position()
        target_counts = self._counts(target_deg)
        start = self.clock.now()
        last, since = None, start
        while True:
            state = self.brick.get_output_state(self._motor)
            count = state.rotation_count
            if timeout_s is None:
                distance = abs(target_deg - count * self.unit.gear_ratio)
                timeout_s = 2.0 * distance / self.speed_deg_s + 1.0
            if count == target_counts:
                return count * self.unit.gear_ratio
            if state.run_state == RunState.IDLE:
                if abs(count - target_counts) <= self.tolerance_counts:
                    return count * self.unit.gear_ratio
                raise self._stalled(target_deg, count, "the brick stopped the motor")
            now = self.clock.now()
            if count != last:
                last, since = count, now
            elif now - since >= self.unit.stall_timeout_s:
                self.stop()
                raise self._stalled(
                    target_deg, count, f"no progress for {self.unit.stall_timeout_s} s"
                )
            if now - start >= timeout_s:
                self.stop()
                raise DeviceTimeout(
                    self.name,
                    f"tilt to {target_deg}°",
                    f"still moving at {count * self.unit.gear_ratio:.3f}° after {timeout_s:.1f} s "
                    f"(expected {self.speed_deg_s}°/s); check motor_power and the battery",
                )
            self.clock.sleep(self.poll_s)

    def stop(self) -> None:
        """Brake the tilt motor where it is."""
        self.brick.set_output_state(
            self._motor,
            power=0,
            mode=OutputMode.MOTORON | OutputMode.BRAKE,
            regulation=RegulationMode.IDLE,
            run_state=RunState.IDLE,
        )
        self._target_deg = None

    def close(self) -> None:
        """Nothing to release: the laser unit closes the brick."""

    def _counts(self, deg: float) -> int:
        return round(deg / self.unit.gear_ratio)

    def _stalled(self, target_deg: float, count: int, why: str) -> MotionStalled:
        return MotionStalled(
            self.name,
            f"tilt to {target_deg}°",
            f"motor {self.unit.motor_port} stopped at {count * self.unit.gear_ratio:.3f}° "
            f"tilt ({count} counts, target {self._counts(target_deg)}): {why}; "
            "check the gears and the battery",
        )
