"""A Dynamixel Protocol 2.0 bus on a pty: servos that answer a driver byte for byte.

A driver opens ``peer.serial_port`` (a pty) exactly as it would open a USB
adapter's ``/dev/ttyUSB0``. A thread reads instruction packets from the pty
master, lets each addressed servo answer (PING, READ, WRITE, SYNC_READ,
SYNC_WRITE, REBOOT; broadcasts as the protocol says) and writes status
packets back. Servos drive the world's arc axis (``_servo.SimServo``).

Faults, at run time or from a scene's fault table: ``no_reply``, ``garbled``
(a reply whose CRC fails; also ``*_rate`` and ``seed``), ``stall_fraction``
(the arc stops short) and ``hardware_error`` (``{servo_id: bits}``).
"""

from __future__ import annotations

import contextlib
import logging
import os
import select
import threading
from collections.abc import Mapping
from typing import Any

from rig.config import LightArc
from rig.devices import RAIL_ROLE, DynamixelServos
from rig.errors import ConfigError
from sim.peers._faults import ReplyFaults, check_fault_keys
from sim.peers._pty import RawPty
from sim.peers.dynamixel._framing import (
    BROADCAST_ID,
    Instruction,
    Packet,
    PacketReader,
    encode_status,
)
from sim.peers.dynamixel._servo import SimServo
from sim.peers.registry import register_peer
from sim.world import World

__all__ = ["DynamixelBusPeer"]

log = logging.getLogger(__name__)
_INSTRUCTION_ERROR = 2
_CRC_ERROR = 3
_DATA_LENGTH_ERROR = 5


class DynamixelBusPeer:
    """Servos ``ids`` on one simulated bus, moving ``world``'s ``axis``.

    Parameters
    ----------
    world : World
        The simulated rig; goal positions move ``axis``.
    servos : DynamixelServos
        The servos on the bus (``ids``) and their gearing (default: the world
        config's light arc).
    operating_mode : int
        3 (position, 0..4095 within the position limits) or 4 (extended).
    faults : mapping
        The fault table (see the module docstring).
    """

    name = "dynamixel bus"
    FAULT_KEYS = ReplyFaults.KEYS | {"stall_fraction", "hardware_error"}

    def __init__(
        self,
        world: World,
        *,
        servos: DynamixelServos | None = None,
        axis: str = "arc",
        operating_mode: int = 4,
        faults: Mapping[str, Any] | None = None,
    ):
        gearing = servos or world.config.light_arc.device
        self.world = world
        self.axis = axis
        self.servos = {
            i: SimServo(i, world, gearing=gearing, axis=axis, operating_mode=operating_mode)
            for i in gearing.ids
        }
        faults = dict(faults or {})
        check_fault_keys(self.name, faults, set(self.FAULT_KEYS))
        self.faults = ReplyFaults.from_dict(faults)
        self._held = b""  # a late status packet, sent before the next one
        self._pty: RawPty | None = None
        self._wake_r = self._wake_w = -1
        self._thread: threading.Thread | None = None
        self._reader = PacketReader()
        if faults.get("stall_fraction") is not None:
            self.set_stall(faults["stall_fraction"])
        for servo_id, bits in dict(faults.get("hardware_error", {})).items():
            self.set_hardware_error(int(servo_id), int(bits))

    @property
    def serial_port(self) -> str:
        """The pty a driver opens as its ``serial_port`` (after ``start``)."""
        if self._pty is None:
            raise RuntimeError(f"{self.name}: not started")
        return self._pty.path

    # -- lifecycle -------------------------------------------------------------
    def start(self) -> DynamixelBusPeer:
        """Open the pty and start answering; returns ``self``."""
        self._pty = RawPty()
        self._wake_r, self._wake_w = os.pipe()
        self._thread = threading.Thread(target=self._serve, name="dynamixel-bus", daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        """Stop answering, join the thread, close the pty; idempotent."""
        if self._wake_w >= 0:
            os.write(self._wake_w, b"x")
        if self._thread is not None:
            self._thread.join(timeout=5)
            self._thread = None
        for fd in (self._wake_r, self._wake_w):
            with contextlib.suppress(OSError):
                os.close(fd)
        self._wake_r = self._wake_w = -1
        if self._pty is not None:
            self._pty.close()
            self._pty = None

    def connect(self, section):
        """``section`` with its Dynamixel device on this bus's pty."""
        device = section.device.model_copy(update={"serial_port": self.serial_port})
        return section.model_copy(update={"device": device})

    def __enter__(self) -> DynamixelBusPeer:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()

    # -- fault injection -------------------------------------------------------
    def set_stall(self, fraction: float | None) -> None:
        """Make the arc's next moves stop at ``fraction`` of the way (None: no stall)."""
        if fraction is not None and not 0.0 <= fraction < 1.0:
            raise ConfigError(f"{self.name}: stall_fraction={fraction} must be in [0, 1)")
        self.world.axis(self.axis).stall_fraction = fraction

    def set_hardware_error(self, servo_id: int, bits: int) -> None:
        """Set servo ``servo_id``'s hardware error status (0 clears; REBOOT clears too)."""
        if servo_id not in self.servos:
            raise ConfigError(
                f"{self.name}: no servo {servo_id} on the bus; servos are {sorted(self.servos)}"
            )
        self.servos[servo_id].set_hardware_error(bits)

    # -- the bus thread --------------------------------------------------------
    def _serve(self) -> None:
        assert self._pty is not None
        master = self._pty.master
        while True:
            readable, _, _ = select.select([master, self._wake_r], [], [])
            if self._wake_r in readable:
                return
            try:
                data = os.read(master, 4096)
            except OSError:
                continue
            for packet in self._reader.feed(data):
                for reply in self._answer(packet):
                    self._send(master, reply)

    def _send(self, master: int, reply: bytes) -> None:
        decision = self.faults.decide()
        held, self._held = self._held, b""
        if decision == "drop":
            log.info("%s: fault: status packet dropped", self.name)
            reply = b""
        elif decision == "garble":
            log.info("%s: fault: status packet garbled", self.name)
            reply = reply[:-1] + bytes([reply[-1] ^ 0xA5])
        elif decision == "late":
            log.info("%s: fault: status packet held back until the next", self.name)
            self._held, reply = reply, b""
        if held + reply:
            os.write(master, held + reply)

    def _answer(self, packet: Packet) -> list[bytes]:
        """The status packets the bus sends back for one instruction packet."""
        if packet.servo_id == BROADCAST_ID:
            targets = list(self.servos.values())
        elif packet.servo_id in self.servos:
            targets = [self.servos[packet.servo_id]]
        else:
            return []  # nobody with that id: silence, as on a real bus
        if not packet.crc_ok:
            return (
                []
                if packet.servo_id == BROADCAST_ID
                else [encode_status(packet.servo_id, _CRC_ERROR | targets[0].alert())]
            )
        inst, params = packet.instruction, packet.params
        if inst == Instruction.PING:
            return [
                encode_status(s.servo_id, s.alert(), s.read(0, 2)[1] + s.read(6, 1)[1])
                for s in targets
            ]
        if inst == Instruction.SYNC_READ:
            return self._sync_read(params) if packet.servo_id == BROADCAST_ID else []
        if inst == Instruction.SYNC_WRITE:
            if packet.servo_id == BROADCAST_ID:
                self._sync_write(params)
            return []
        replies = [self._unicast(servo, inst, params) for servo in targets]
        return [] if packet.servo_id == BROADCAST_ID else replies

    def _unicast(self, servo: SimServo, inst: int, params: bytes) -> bytes:
        if inst == Instruction.READ:
            if len(params) != 4:
                return encode_status(servo.servo_id, _DATA_LENGTH_ERROR | servo.alert())
            address = int.from_bytes(params[:2], "little")
            error, data = servo.read(address, int.from_bytes(params[2:4], "little"))
            return encode_status(servo.servo_id, error | servo.alert(), data)
        if inst == Instruction.WRITE:
            if len(params) < 3:
                return encode_status(servo.servo_id, _DATA_LENGTH_ERROR | servo.alert())
            error = servo.write(int.from_bytes(params[:2], "little"), params[2:])
            return encode_status(servo.servo_id, error | servo.alert())
        if inst == Instruction.REBOOT:
            servo.reboot()
            return encode_status(servo.servo_id, 0)
        return encode_status(servo.servo_id, _INSTRUCTION_ERROR | servo.alert())

    def _sync_read(self, params: bytes) -> list[bytes]:
        address = int.from_bytes(params[:2], "little")
        length = int.from_bytes(params[2:4], "little")
        replies = []
        for servo_id in params[4:]:
            servo = self.servos.get(servo_id)
            if servo is not None:
                error, data = servo.read(address, length)
                replies.append(encode_status(servo_id, error | servo.alert(), data))
        return replies

    def _sync_write(self, params: bytes) -> None:
        address = int.from_bytes(params[:2], "little")
        length = int.from_bytes(params[2:4], "little")
        body = params[4:]
        for start in range(0, len(body) - length, length + 1):
            servo = self.servos.get(body[start])
            if servo is not None:
                error = servo.write(address, body[start + 1 : start + 1 + length])
                if error:
                    log.info(
                        "%s: sync write to servo %d refused (error %d)",
                        self.name,
                        servo.servo_id,
                        error,
                    )


@register_peer("light_arc", "dynamixel")
def start_bus(
    section: LightArc, world: World, *, faults: Mapping[str, Any], serial: bool
) -> DynamixelBusPeer:
    """The section's servos on a pty, turning the world's arc, started."""
    return DynamixelBusPeer(world, servos=section.device, faults=faults).start()


@register_peer(RAIL_ROLE, "dynamixel")
def start_rail_bus(
    section, world: World, *, faults: Mapping[str, Any], serial: bool
) -> DynamixelBusPeer:
    """The Bonn lab's rail servos on a pty, moving the world's rail axis, started."""
    return DynamixelBusPeer(world, servos=section.device, axis="rail", faults=faults).start()
