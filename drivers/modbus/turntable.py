"""The turntable: a stepper drive on Modbus (TCP or RTU) with a configurable register map.

The drive takes a target position and a command code (go / home / stop) in
holding registers and reports its actual position and a status word (moving,
in position, fault, homed); ``rig.devices.DriveRegisters`` maps them, since
drives differ; positions are counts of ``1 / units_per_deg`` degree. Waiting
polls the drive on the injected clock, so a simulated session in virtual time
does not wait in real time.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import Literal

from drivers.errors import DeviceFault, DeviceTimeout, MotionStalled
from drivers.modbus._link import ModbusLink
from drivers.registry import register
from rig.clock import Clock
from rig.config import Axis, Turntable
from rig.devices import RAIL_ROLE, DriveRegisters, ModbusDrive
from rig.errors import KinematicsError

__all__ = ["DriveStatus", "ModbusTurntable"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class DriveStatus:
    """The drive's status word and its flags, decoded through the register map."""

    word: int
    moving: bool
    in_position: bool
    fault: bool
    homed: bool

    @classmethod
    def decode(cls, word: int, registers: DriveRegisters) -> DriveStatus:
        """Read the flags out of a status ``word`` at the map's bit positions."""
        return cls(
            word=word,
            moving=bool(word >> registers.moving_bit & 1),
            in_position=bool(word >> registers.in_position_bit & 1),
            fault=bool(word >> registers.fault_bit & 1),
            homed=bool(word >> registers.homed_bit & 1),
        )

    def __str__(self) -> str:
        flags = [n for n in ("moving", "in_position", "fault", "homed") if getattr(self, n)]
        return f"0x{self.word:04x} ({', '.join(flags) or 'idle'})"


class ModbusTurntable:
    """Driver of a stepper drive turning an axis; satisfies ``drivers.interfaces.Axis``.

    Parameters
    ----------
    drive : ModbusDrive
        The drive's address (TCP host/port or RTU serial port), unit id,
        retries and register map.
    axis : Axis
        Travel limits (deg), the speed/acceleration loaded into the drive and
        the settle time.
    clock : Clock
        Time for polling and backoff.
    poll_s : float
        Interval between status polls while waiting for a move.
    name : str
        The device's name in errors.
    """

    def __init__(
        self,
        drive: ModbusDrive,
        *,
        axis: Axis,
        clock: Clock,
        poll_s: float = 0.05,
        name: str = "turntable",
    ):
        if poll_s <= 0:
            raise ValueError(f"{name}: poll_s={poll_s} must be > 0")
        self.name = name
        self.axis = axis
        self.settle_s = axis.settle_s
        self.registers = drive.registers
        self._clock = clock
        self._poll_s = poll_s
        self._link = ModbusLink(drive, device=name, clock=clock)
        self._order: Literal["big", "little"] = (
            "big" if drive.registers.word_order == "high_first" else "little"
        )
        self._target_deg: float | None = None
        self._profile_loaded = False

    # -- commands ------------------------------------------------------------
    def home(self, timeout_s: float | None = None) -> None:
        """Run the drive's homing sequence and wait until it reports homed at 0°."""
        self._load_profile("home")
        self._target_deg = 0.0
        self._command(self.registers.home_code, "home")
        if timeout_s is None:
            timeout_s = self._default_timeout_s(self.axis.max_deg - self.axis.min_deg)
        self.wait_until_settled(timeout_s, operation="home")
        status = self.status("home")
        if not status.homed:
            raise DeviceFault(self.name, "home", f"homing ended without the homed bit: {status}")

    def move_to(self, deg: float) -> None:
        """Start a move to ``deg`` (within the axis limits); returns at once."""
        deg = float(deg)
        if not self.axis.min_deg <= deg <= self.axis.max_deg:
            raise KinematicsError(
                f"{self.name}: move_to {deg}° is outside the axis range "
                f"[{self.axis.min_deg}°, {self.axis.max_deg}°]"
            )
        self._load_profile("move_to")
        counts = round(deg * self.registers.units_per_deg)
        self._link.write_int32(
            self.registers.target_position, counts, word_order=self._order, operation="move_to"
        )
        self._target_deg = deg
        self._command(self.registers.go_code, "move_to")

    def stop(self) -> None:
        """Decelerate and stop; the next wait returns where the axis stopped."""
        self._command(self.registers.stop_code, "stop")
        self._target_deg = None

    # -- state ---------------------------------------------------------------
    def position(self) -> float:
        """The actual position (deg) the drive reports."""
        counts = self._link.read_int32(
            self.registers.actual_position, word_order=self._order, operation="position"
        )
        return counts / self.registers.units_per_deg

    def status(self, operation: str = "status") -> DriveStatus:
        """The drive's decoded status word."""
        word = self._link.read_holding(self.registers.status, 1, operation=operation)[0]
        return DriveStatus.decode(word, self.registers)

    def wait_until_settled(
        self, timeout_s: float | None = None, *, operation: str = "move_to"
    ) -> float:
        """Poll until the drive is in position; return the actual position (deg).

        A drive may take one poll to raise its moving bit after a command, so
        "not moving and not in position" must be seen on two polls in a row
        before it counts as a stall.

        Raises
        ------
        DeviceFault
            The drive's fault bit is set.
        MotionStalled
            The drive stopped short of the target (names target and stop).
        DeviceTimeout
            Still moving after ``timeout_s`` (default: twice the move time + 1 s).
        """
        target = self._target_deg
        start = self.position()
        if timeout_s is None:
            timeout_s = self._default_timeout_s(0.0 if target is None else target - start)
        deadline = self._clock.now() + timeout_s
        idle_polls = 0
        while True:
            status = self.status(operation)
            where = self.position()
            if status.fault:
                raise DeviceFault(
                    self.name,
                    operation,
                    f"the drive reports a fault {status} at {where:.2f}°"
                    + ("" if target is None else f" moving to {target:.2f}°"),
                )
            if status.in_position or (target is None and not status.moving):
                log.debug("%s: settled at %.3f° (%s)", self.name, where, status)
                return where
            idle_polls = 0 if status.moving else idle_polls + 1
            if idle_polls >= 2:
                raise MotionStalled(
                    self.name,
                    operation,
                    f"stopped at {where:.2f}° short of the target {target:.2f}° "
                    f"(status {status}); check for a jam or a slipping belt",
                )
            if self._clock.now() >= deadline:
                raise DeviceTimeout(
                    self.name,
                    operation,
                    f"still moving at {where:.2f}° towards {target}° after {timeout_s:.1f} s",
                )
            self._clock.sleep(self._poll_s)

    def close(self) -> None:
        """Close the connection; idempotent. The drive keeps its position."""
        self._link.close()

    # -- internals -----------------------------------------------------------
    def _command(self, code: int, operation: str) -> None:
        self._link.write_holding(self.registers.command, [code], operation=operation)

    def _load_profile(self, operation: str) -> None:
        if self._profile_loaded:
            return
        units = self.registers.units_per_deg
        speed = round(self.axis.speed_deg_s * units)
        accel = round(self.axis.accel_deg_s2 * units)
        for field, value in (("speed", speed), ("acceleration", accel)):
            if not 1 <= value <= 0xFFFF:
                raise ValueError(
                    f"{self.name}: {field} {value} counts does not fit the drive's 16-bit "
                    f"register; lower units_per_deg ({units}) or the axis {field}"
                )
        self._link.write_holding(self.registers.speed, [speed], operation=operation)
        self._link.write_holding(self.registers.acceleration, [accel], operation=operation)
        self._profile_loaded = True

    def _default_timeout_s(self, delta_deg: float) -> float:
        return 2.0 * float(self.axis.move_time_s(delta_deg)) + self.axis.settle_s + 1.0


@register("turntable", "modbus")
@register(RAIL_ROLE, "modbus")
def open_turntable(section: Turntable, *, clock: Clock) -> ModbusTurntable:
    """The turntable of a rig config (or the Bonn lab's rail), on its Modbus drive."""
    return ModbusTurntable(section.device, axis=section.axis, clock=clock)
