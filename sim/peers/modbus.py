"""Simulated Modbus devices: the turntable's stepper drive and the lamp bank.

Each is a pymodbus server (TCP on loopback, or RTU on a pty) whose registers
are the device's register map (``docs/devices.md``) and whose behaviour is
the simulated world's: writing a target and the *go* command moves the
world's turntable axis, reads of the actual position and status come from the
world at the clock's now, coils switch the world's lamps and the light-sensor
inputs report which lamps really glow.

Faults, at run time or from a scene's fault table: ``no_reply``, ``garbled``
(and their ``_rate`` forms, with ``seed``) for any peer; ``stall_fraction``
and ``drive_fault`` for the drive; ``dead_lamps`` and ``stuck_lamps`` for the
lamp bank.
"""

from __future__ import annotations

import logging
from collections.abc import Iterable, Mapping
from typing import Any, Literal

from pymodbus.client.mixin import ModbusClientMixin
from pymodbus.constants import ExcCodes
from pymodbus.simulator import DataType, SimData, SimDevice

from rig.config import LampBank, Turntable
from rig.devices import DriveRegisters, LampBankRegisters
from rig.errors import ConfigError
from sim.peers._faults import ReplyFaults, check_fault_keys
from sim.peers._modbus_server import ModbusServerThread
from sim.peers.registry import register_peer
from sim.world import World

__all__ = ["LampBankPeer", "TurntableDrivePeer"]

log = logging.getLogger(__name__)
_INT32 = ModbusClientMixin.DATATYPE.INT32


class _ModbusPeer:
    """What both simulated devices share: a server thread, reply faults, start/stop."""

    name = "modbus peer"
    FAULT_KEYS: frozenset[str] = ReplyFaults.KEYS

    def __init__(
        self,
        device: SimDevice,
        *,
        transport: Literal["tcp", "rtu"],
        host: str,
        port: int,
        baudrate: int,
        faults: Mapping[str, Any] | None,
    ):
        faults = dict(faults or {})
        check_fault_keys(self.name, faults, set(self.FAULT_KEYS))
        self.faults = ReplyFaults.from_dict(faults)
        self._transport = transport
        self._host = host
        self._server = ModbusServerThread(
            device,
            name=self.name.replace(" ", "-"),
            transport=transport,
            host=host,
            port=port,
            baudrate=baudrate,
            faults=self.faults,
        )
        self._device_faults = {k: v for k, v in faults.items() if k not in ReplyFaults.KEYS}

    @property
    def port(self) -> int:
        """TCP port served (after ``start``; an ephemeral one when asked for 0)."""
        return self._server.port

    @property
    def serial_port(self) -> str | None:
        """RTU: the pty a driver opens as its ``serial_port``."""
        return self._server.serial_port

    def start(self):
        """Start serving; returns ``self`` once the port is open."""
        self._server.start()
        return self

    def stop(self) -> None:
        """Stop serving, close every connection and port; idempotent."""
        self._server.stop()

    def connect(self, section):
        """``section`` with its Modbus device on this peer (loopback port or pty)."""
        if self._transport == "tcp":
            update = {"protocol": "tcp", "host": self._host, "port": self.port}
        else:
            update = {"protocol": "rtu", "serial_port": self.serial_port}
        return section.model_copy(update={"device": section.device.model_copy(update=update)})

    def __enter__(self):
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()


class TurntableDrivePeer(_ModbusPeer):
    """A stepper drive answering a ``DriveRegisters`` map, moving ``world``'s axis.

    Commands: *go* moves to the target register's position, *home* moves to
    0° and raises the homed bit on arrival, *stop* halts where the axis is. A
    target outside the axis limits, an unknown command code or a zero
    speed/acceleration is refused with ILLEGAL_VALUE, and writes to the
    read-only actual position and status with ILLEGAL_ADDRESS, as drives do.
    While ``drive_fault`` is set the fault bit is up and *go* does nothing.
    The simulated motion follows the rig config's axis profile; the speed and
    acceleration registers are stored and read back.
    """

    name = "turntable drive"
    FAULT_KEYS = ReplyFaults.KEYS | {"stall_fraction", "drive_fault"}

    def __init__(
        self,
        world: World,
        *,
        registers: DriveRegisters | None = None,
        axis: str = "turntable",
        unit_id: int = 1,
        transport: Literal["tcp", "rtu"] = "tcp",
        host: str = "127.0.0.1",
        port: int = 0,
        baudrate: int = 115200,
        faults: Mapping[str, Any] | None = None,
    ):
        self.world = world
        self.axis = axis
        self.registers = registers or DriveRegisters()
        self._limits = world.axis(axis).limits
        self._order: Literal["big", "little"] = (
            "big" if self.registers.word_order == "high_first" else "little"
        )
        self._commanded_deg = world.position(axis)
        self._drive_fault = False
        self._homed = False
        self._homing = False
        super().__init__(
            SimDevice(id=unit_id, simdata=self._simdata(), action=self._action),
            transport=transport,
            host=host,
            port=port,
            baudrate=baudrate,
            faults=faults,
        )
        self.set_stall(self._device_faults.get("stall_fraction"))
        self.set_drive_fault(bool(self._device_faults.get("drive_fault", False)))

    # -- fault injection -------------------------------------------------------
    def set_stall(self, fraction: float | None) -> None:
        """Make the next moves stop at ``fraction`` of their way (None: no stall)."""
        if fraction is not None and not 0.0 <= fraction < 1.0:
            raise ConfigError(f"{self.name}: stall_fraction={fraction} must be in [0, 1)")
        self.world.axis(self.axis).stall_fraction = fraction

    def set_drive_fault(self, fault: bool) -> None:
        """Raise (or clear) the drive's fault bit; a faulted drive ignores *go*."""
        self._drive_fault = fault

    # -- the register map ------------------------------------------------------
    def _simdata(self) -> list[SimData]:
        r = self.registers
        units = r.units_per_deg
        regs = DataType.REGISTERS
        return [
            SimData(r.target_position, values=[0, 0], datatype=regs),
            SimData(r.actual_position, values=[0, 0], datatype=regs, readonly=True),
            SimData(r.status, values=0, datatype=regs, readonly=True),
            SimData(r.command, values=0, datatype=regs),
            SimData(
                r.speed, values=min(0xFFFF, round(self._limits.speed_deg_s * units)), datatype=regs
            ),
            SimData(
                r.acceleration,
                values=min(0xFFFF, round(self._limits.accel_deg_s2 * units)),
                datatype=regs,
            ),
        ]

    async def _action(
        self,
        function_code: int,
        start_address: int,
        address: int,
        count: int,
        registers: list[int],
        set_values: list[int] | list[bool] | None,
    ) -> ExcCodes | None:
        r = self.registers
        if set_values is None:  # a read (pymodbus also reads back after a write)
            self._refresh(registers, start_address)
            return None
        pending = list(registers)
        pending[address - start_address : address - start_address + count] = [
            int(v) for v in set_values or []
        ]
        written = range(address, address + count)
        for reg in (r.speed, r.acceleration):
            if reg in written and pending[reg - start_address] == 0:
                return ExcCodes.ILLEGAL_VALUE
        if r.command in written:
            return self._execute(pending[r.command - start_address], pending, start_address)
        return None

    def _refresh(self, registers: list[int], start: int) -> None:
        r = self.registers
        moving = self.world.is_moving(self.axis)
        deg = self.world.position(self.axis)
        counts = round(deg * r.units_per_deg)
        words = ModbusClientMixin.convert_to_registers(counts, _INT32, word_order=self._order)
        registers[r.actual_position - start : r.actual_position - start + 2] = words
        in_position = not moving and abs(deg - self._commanded_deg) * r.units_per_deg <= 1.0
        if self._homing and not moving:
            self._homing = False
            self._homed = in_position
        status = (
            moving << r.moving_bit
            | in_position << r.in_position_bit
            | self._drive_fault << r.fault_bit
            | self._homed << r.homed_bit
        )
        registers[r.status - start] = status

    def _execute(self, code: int, pending: list[int], start: int) -> ExcCodes | None:
        r = self.registers
        if code == r.go_code:
            first = r.target_position - start
            counts = ModbusClientMixin.convert_from_registers(
                pending[first : first + 2], _INT32, word_order=self._order
            )
            deg = int(counts) / r.units_per_deg
            if not self._limits.min_deg <= deg <= self._limits.max_deg:
                return ExcCodes.ILLEGAL_VALUE
            if self._drive_fault:
                log.info("%s: go to %.2f° ignored: drive in fault", self.name, deg)
                return None
            self._move(deg)
        elif code == r.home_code:
            self._homing = True
            self._homed = False
            self._move(0.0)
        elif code == r.stop_code:
            self._move(self.world.position(self.axis))
        else:
            return ExcCodes.ILLEGAL_VALUE
        return None

    def _move(self, deg: float) -> None:
        self._commanded_deg = deg
        self.world.move(self.axis, deg)


class LampBankPeer(_ModbusPeer):
    """A lamp bank answering the ``LampBankRegisters`` layout, switching ``world``'s lamps.

    Coils switch lamps (``World.set_lamp``); a discrete input per lamp reads 1
    while that lamp is on and not dead (``World.dead_lamps``); with dimming,
    holding registers store levels in ``0..dim_full_scale`` (larger values are
    refused with ILLEGAL_VALUE). Faults: ``dead_lamps`` (stay dark) and
    ``stuck_lamps`` (a welded relay: the light sensor sees light whatever the coil).
    """

    name = "lamp bank"
    FAULT_KEYS = ReplyFaults.KEYS | {"dead_lamps", "stuck_lamps"}

    def __init__(
        self,
        world: World,
        *,
        lamp_ids: Iterable[str] | None = None,
        registers: LampBankRegisters | None = None,
        unit_id: int = 1,
        transport: Literal["tcp", "rtu"] = "tcp",
        host: str = "127.0.0.1",
        port: int = 0,
        baudrate: int = 115200,
        faults: Mapping[str, Any] | None = None,
    ):
        self.world = world
        self.lamp_ids = tuple(lamp_ids or (lamp.id for lamp in world.config.lamps))
        self.registers = registers or LampBankRegisters()
        super().__init__(
            SimDevice(id=unit_id, simdata=self._simdata(), action=self._action),
            transport=transport,
            host=host,
            port=port,
            baudrate=baudrate,
            faults=faults,
        )
        self._stuck: set[str] = set()
        for lamp in self._device_faults.get("dead_lamps", ()):
            self.kill_lamp(lamp)
        for lamp in self._device_faults.get("stuck_lamps", ()):
            self.stick_lamp(lamp)

    # -- fault injection -------------------------------------------------------
    def kill_lamp(self, lamp_id: str) -> None:
        """Make ``lamp_id`` stay dark when switched on."""
        self._check(lamp_id)
        self.world.dead_lamps.add(lamp_id)

    def stick_lamp(self, lamp_id: str) -> None:
        """Weld ``lamp_id``'s relay shut: it glows whatever its coil says."""
        self._check(lamp_id)
        self._stuck.add(lamp_id)

    def revive_lamp(self, lamp_id: str) -> None:
        """Replace the bulb and relay of ``lamp_id``."""
        self.world.dead_lamps.discard(lamp_id)
        self._stuck.discard(lamp_id)

    def _check(self, lamp_id: str) -> None:
        if lamp_id not in self.lamp_ids:
            raise ConfigError(f"{self.name}: unknown lamp {lamp_id!r}; valid are {self.lamp_ids}")

    # -- the register map ------------------------------------------------------
    def _simdata(self) -> tuple[list[SimData], list[SimData], list[SimData], list[SimData]]:
        r, n = self.registers, len(self.lamp_ids)
        coils = [SimData(r.coils, values=[False] * n, datatype=DataType.BITS)]
        sensors = [
            SimData(r.light_sensors, values=[False] * n, datatype=DataType.BITS, readonly=True)
        ]
        dimmers = (
            [SimData(r.dimmers, values=[r.dim_full_scale] * n, datatype=DataType.REGISTERS)]
            if r.dimming
            else [SimData(0, datatype=DataType.INVALID)]
        )
        nothing = [SimData(0, datatype=DataType.INVALID)]
        return coils, sensors, dimmers, nothing

    async def _action(
        self,
        function_code: int,
        start_address: int,
        address: int,
        count: int,
        registers: list[int],
        set_values: list[int] | list[bool] | None,
    ) -> ExcCodes | None:
        r = self.registers
        if function_code in (1, 2):  # coils / light sensors: bits from the world
            first = r.coils if function_code == 1 else r.light_sensors
            lit = self.world.snapshot().lamps_on | self._stuck
            on = lit if function_code == 2 else set(self.world.lamps_switched_on())
            self._pack_bits(registers, start_address, first, [lamp in on for lamp in self.lamp_ids])
        elif function_code in (5, 15) and set_values is not None:
            # For bit blocks pymodbus passes ``count`` in registers, not bits.
            for offset, value in enumerate(set_values or []):
                channel = address + offset - r.coils
                if 0 <= channel < len(self.lamp_ids):
                    self.world.set_lamp(self.lamp_ids[channel], bool(value))
        elif set_values is not None and any(int(v) > r.dim_full_scale for v in set_values):
            return ExcCodes.ILLEGAL_VALUE
        return None

    @staticmethod
    def _pack_bits(registers: list[int], start_register: int, first_bit: int, bits: list[bool]):
        """Write ``bits`` (from bit address ``first_bit``) into a packed bit block."""
        for i, value in enumerate(bits):
            index = first_bit + i - 16 * start_register
            word, bit = divmod(index, 16)
            registers[word] = (
                registers[word] | (1 << bit) if value else registers[word] & ~(1 << bit)
            )


def _start(peer_class, section, world: World, faults: Mapping[str, Any], serial: bool, **axis):
    device = section.device
    return peer_class(
        world,
        **axis,
        registers=device.registers,
        unit_id=device.unit_id,
        transport="rtu" if serial else "tcp",
        baudrate=device.baudrate,
        faults=faults,
    ).start()


@register_peer("turntable", "modbus")
def start_drive(
    section: Turntable, world: World, *, faults: Mapping[str, Any], serial: bool
) -> TurntableDrivePeer:
    """A drive with the section's register map and unit id, started (TCP, or RTU on a pty)."""
    return _start(TurntableDrivePeer, section, world, faults, serial)


@register_peer("rail", "modbus")
def start_rail_drive(
    section, world: World, *, faults: Mapping[str, Any], serial: bool
) -> TurntableDrivePeer:
    """The Bonn lab's rail on a stepper drive: the world's rail axis, started."""
    return _start(TurntableDrivePeer, section, world, faults, serial, axis="rail")


@register_peer("lamp_bank", "modbus")
def start_lamp_bank(
    section: LampBank, world: World, *, faults: Mapping[str, Any], serial: bool
) -> LampBankPeer:
    """A bank with the light arc's lamps and the section's layout and unit id, started."""
    return _start(LampBankPeer, section, world, faults, serial)
