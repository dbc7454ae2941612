"""The LEGO laser unit: an NXT motor tilts the laser sheet, another output powers the diode.

Motor ``laser.motor_port`` turns the sheet through a gearbox of
``laser.gear_ratio`` degrees of tilt per motor degree. The brick has no
absolute encoder: the rotation count (RESETMOTORPOSITION, absolute) is zeroed
with the sheet at tilt 0 (``zero_tilt``), and every tilt is read back from it.
A move is a SETOUTPUTSTATE with a tacho limit of the remaining motor degrees,
so re-sending it after a lost reply still ends at the same absolute tilt.

The diode hangs on output ``laser.laser_port`` driven at constant power
(``laser.laser_power`` %, motor on, unregulated): an NXT output is the only
place with switchable 4.3–9 V on the brick, and unlike a powered sensor type
(SETINPUTMODE) it can be read back with GETOUTPUTSTATE.
"""

from __future__ import annotations

import logging

from drivers.errors import DeviceError, DeviceFault, MotionStalled
from drivers.nxt._brick import NxtBrick
from drivers.nxt._telegram import MOTOR_PORTS, OutputMode, RegulationMode, RunState
from drivers.retry import with_retries
from rig.clock import Clock
from rig.config import Laser

__all__ = ["NxtLaser"]

log = logging.getLogger(__name__)

_MOVE = OutputMode.MOTORON | OutputMode.BRAKE | OutputMode.REGULATED
_LASER_ON = OutputMode.MOTORON


class NxtLaser:
    """Tilt and switch the laser sheet of one LEGO laser unit (synchronous).

    Parameters
    ----------
    brick : an open ``NxtBrick``; closed by ``close``.
    laser : the rig config's laser section (ports, gear ratio, power, limits).
    clock : injected time for polling and stall detection.
    poll_s : interval between GETOUTPUTSTATE polls while waiting for a move.
    tolerance_counts : how far (motor degrees) a finished move may end from its
        target (a braked NXT motor overshoots a few degrees) before it counts as
        stopped short.
    """

    def __init__(
        self,
        brick: NxtBrick,
        laser: Laser,
        *,
        clock: Clock,
        poll_s: float = 0.05,
        tolerance_counts: int = 5,
    ):
        self.brick = brick
        self.laser = laser
        self.clock = clock
        self.poll_s = poll_s
        self.tolerance_counts = tolerance_counts
        self.device = brick.device
        self._motor = MOTOR_PORTS[laser.motor_port]
        self._diode = MOTOR_PORTS[laser.laser_port]

    @classmethod
    def open(
        cls, laser: Laser, *, clock: Clock, usb_backend=None, poll_s: float = 0.05
    ) -> NxtLaser:
        """Open the brick ``laser.brick`` names (USB or serial) and wrap it."""
        brick = NxtBrick.open(
            laser.brick, clock=clock, device="laser brick", usb_backend=usb_backend
        )
        return cls(brick, laser, clock=clock, poll_s=poll_s)

    def check_battery(self) -> int:
        """The battery voltage (mV); ``DeviceFault`` below ``laser.min_battery_mv``."""
        mv = self.brick.battery_level_mv()
        if mv < self.laser.min_battery_mv:
            raise DeviceFault(
                self.device,
                "battery check",
                f"battery at {mv} mV, below the minimum {self.laser.min_battery_mv} mV "
                "(motor speed and laser power would drift): charge or replace the cells",
            )
        return mv

    def set_laser(self, on: bool) -> None:
        """Switch the diode's output port on (constant power) or off (float)."""
        self.brick.set_output_state(
            self._diode,
            power=self.laser.laser_power if on else 0,
            mode=_LASER_ON if on else OutputMode.COAST,
            regulation=RegulationMode.IDLE,
            run_state=RunState.RUNNING if on else RunState.IDLE,
        )

    def laser_is_on(self) -> bool:
        state = self.brick.get_output_state(self._diode)
        return bool(state.mode & OutputMode.MOTORON) and state.power != 0

    def zero_tilt(self) -> None:
        """Declare the present sheet position tilt 0 (reset the absolute rotation count)."""
        self.brick.reset_motor_position(self._motor, relative=False)

    def tilt_deg(self) -> float:
        """The sheet's tilt now, from the motor's rotation count (deg)."""
        return self.brick.get_output_state(self._motor).rotation_count * self.laser.gear_ratio

    def _check_target(self, target_deg: float) -> None:
        limit = self.laser.tilt_limit_deg
        if not -limit <= target_deg <= limit:
            raise DeviceError(
                self.device,
                f"tilt to {target_deg}°",
                f"the target is outside the unit's tilt range ±{limit}° (laser.tilt_limit_deg)",
            )

    def start_tilt(self, target_deg: float) -> None:
        """Start turning the sheet to ``target_deg`` and return at once."""
        self._check_target(target_deg)
        target_counts = round(target_deg / self.laser.gear_ratio)

        def attempt() -> None:
            # Re-read the position on every try: a lost reply to a move that did
            # start must not add its distance twice.
            now = self.brick.get_output_state(self._motor, retried=False).rotation_count
            delta = target_counts - now
            if delta == 0:
                return
            power = self.laser.motor_power if delta > 0 else -self.laser.motor_power
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
            device=self.device,
            operation=f"tilt to {target_deg}°",
        )

    def wait_tilt(self, target_deg: float) -> float:
        """Wait until the motor stops; return the tilt reached (deg).

        ``MotionStalled`` (after stopping the motor) when the rotation count has
        not changed for ``laser.stall_timeout_s`` while the brick still runs it.
        """
        target_counts = round(target_deg / self.laser.gear_ratio)
        last = None
        since = self.clock.now()
        while True:
            state = self.brick.get_output_state(self._motor)
            count = state.rotation_count
            if count == target_counts:
                return count * self.laser.gear_ratio
            if state.run_state == RunState.IDLE:
                if abs(count - target_counts) <= self.tolerance_counts:
                    return count * self.laser.gear_ratio
                raise self._stalled(target_deg, count, "the brick stopped the motor")
            if count != last:
                last, since = count, self.clock.now()
            elif self.clock.now() - since >= self.laser.stall_timeout_s:
                self.stop()
                raise self._stalled(
                    target_deg, count, f"no progress for {self.laser.stall_timeout_s} s"
                )
            self.clock.sleep(self.poll_s)

    def _stalled(self, target_deg: float, count: int, why: str) -> MotionStalled:
        target_counts = round(target_deg / self.laser.gear_ratio)
        return MotionStalled(
            self.device,
            f"tilt to {target_deg}°",
            f"motor {self.laser.motor_port} stopped at {count * self.laser.gear_ratio:.3f}° "
            f"tilt ({count} counts, target {target_counts}): {why}; "
            "check the gears and the battery",
        )

    def move_tilt(self, target_deg: float) -> float:
        """``start_tilt`` then ``wait_tilt``: the tilt reached (deg)."""
        self.start_tilt(target_deg)
        return self.wait_tilt(target_deg)

    def stop(self) -> None:
        """Brake the tilt motor where it is."""
        self.brick.set_output_state(
            self._motor,
            power=0,
            mode=OutputMode.MOTORON | OutputMode.BRAKE,
            regulation=RegulationMode.IDLE,
            run_state=RunState.IDLE,
        )

    def close(self) -> None:
        """Switch the diode off (best effort) and close the link."""
        try:
            self.set_laser(False)
        except DeviceError as err:
            log.warning("%s: could not switch the laser off before closing: %s", self.device, err)
        finally:
            self.brick.close()
