"""A fake LEGO NXT brick at the level of direct-command telegrams, backed by the World.

Written from the LEGO MINDSTORMS NXT Bluetooth Developer Kit, Appendix 2
(Direct Commands), not from any driver: telegram ``[type, opcode, payload]``,
type 0x00 (reply required) or 0x80 (no reply); reply ``[0x02, opcode, status,
payload]``, little-endian fields. It answers SETOUTPUTSTATE (0x04),
GETOUTPUTSTATE (0x06), RESETMOTORPOSITION (0x0A) and GETBATTERYLEVEL (0x0B);
any other opcode gets status 0xBE (unknown command opcode).

Wiring of the simulated laser unit (from ``world.config.laser.device``): the motor on
``motor_port`` turns the world's ``laser_tilt`` axis through ``gear_ratio``
degrees of tilt per motor degree, so motion takes world-clock time on the
axis' trapezoidal profile; the output ``laser_port`` switches the world's
laser (on while its mode has MOTORON, power ≠ 0 and run state ≠ IDLE), and
with a second mount the third output switches it with that mount's emitter.

Counters of the tilt motor (motor degrees, rounded to whole counts):
``tacho_count`` since power-on, ``block_tacho_count`` since the last movement
command or RESETMOTORPOSITION(relative=1), ``rotation_count`` since
RESETMOTORPOSITION(relative=0). A move with a tacho limit runs (run state
RUNNING) until the count reaches the limit; a stalled axis never does.
"""

from __future__ import annotations

import logging
import struct
import threading
from dataclasses import dataclass

from sim.world import World

__all__ = ["FakeNxtBrick", "NxtFaults"]

log = logging.getLogger(__name__)

_PORTS = {"A": 0, "B": 1, "C": 2}
_MOTORON = 0x01
_RUN_IDLE = 0x00
_RUN_RUNNING = 0x20
_SET_OUTPUT_STATE = 0x04
_GET_OUTPUT_STATE = 0x06
_RESET_MOTOR_POSITION = 0x0A
_GET_BATTERY_LEVEL = 0x0B
# telegram length per opcode, type and opcode bytes included
_LENGTHS = {
    _SET_OUTPUT_STATE: 12,
    _GET_OUTPUT_STATE: 3,
    _RESET_MOTOR_POSITION: 4,
    _GET_BATTERY_LEVEL: 2,
}

_OK = 0x00
_UNKNOWN_OPCODE = 0xBE
_INSANE_PACKET = 0xBF
_OUT_OF_RANGE = 0xC0
_BAD_OUTPUT = 0xF0


@dataclass
class NxtFaults:
    """Faults to inject; counters apply to the next so many telegrams.

    ``lost_replies``: the command is executed but its reply never arrives.
    ``garbled_replies``: the reply arrives with its first byte corrupted.
    ``deaf``: the brick answers nothing at all (switched off, out of range).
    ``battery_mv``: what GETBATTERYLEVEL reports (low battery: below 6500).
    ``stall_fraction``: tilt moves stop at this fraction of their distance.
    """

    lost_replies: int = 0
    garbled_replies: int = 0
    deaf: bool = False
    battery_mv: int = 8200
    stall_fraction: float | None = None


@dataclass
class _Output:
    power: int = 0
    mode: int = 0
    regulation: int = 0
    turn_ratio: int = 0
    run_state: int = _RUN_IDLE
    tacho_limit: int = 0


class FakeNxtBrick:
    """The brick: ``handle(telegram) -> reply or None``; thread-safe."""

    def __init__(self, world: World, *, faults: NxtFaults | None = None):
        self.world = world
        self.faults = faults or NxtFaults()
        laser = world.config.laser
        self.gear_ratio = laser.device.gear_ratio
        self.tilt_port = _PORTS[laser.device.motor_port]
        ports = laser.device.diode_ports(len(laser.mount_theta_deg))
        self.diode_ports = {_PORTS[port]: mount for mount, port in enumerate(ports)}
        self.tilt_limit_deg = laser.tilt_limit_deg
        self.outputs = [_Output() for _ in _PORTS]
        self._target_motor_deg: float | None = None
        self._block_zero = 0.0
        self._rotation_zero = 0.0
        self.telegrams = 0  # received, for tests and logs
        self._lock = threading.Lock()

    # -- the tilt motor, in motor degrees -------------------------------------------

    def _motor_deg(self) -> float:
        return self.world.position("laser_tilt") / self.gear_ratio

    def _tilt_running(self) -> bool:
        if self._target_motor_deg is None:
            return False
        return abs(self._motor_deg() - self._target_motor_deg) >= 0.5

    def _drive_tilt(self, out: _Output) -> None:
        now = self._motor_deg()
        axis = self.world.axis("laser_tilt")
        if out.mode & _MOTORON and out.power != 0 and out.run_state != _RUN_IDLE:
            direction = 1 if out.power > 0 else -1
            if out.tacho_limit > 0:
                target = now + direction * out.tacho_limit
            else:  # no limit: run until the mechanical end stop
                target = direction * self.tilt_limit_deg / self.gear_ratio
            self._target_motor_deg = target
            self._block_zero = now
            # Command first (it starts from where the axis is, stalled or not),
            # then arm the stall for the new move.
            self.world.move("laser_tilt", target * self.gear_ratio)
            axis.stall_fraction = self.faults.stall_fraction
        else:  # brake or coast: stop where it is
            self._target_motor_deg = None
            self.world.move("laser_tilt", now * self.gear_ratio)
            axis.stall_fraction = None

    # -- telegrams --------------------------------------------------------------------

    def handle(self, telegram: bytes) -> bytes | None:
        """Answer one telegram (without transport framing); None: no reply is sent."""
        with self._lock:
            self.telegrams += 1
            if self.faults.deaf or len(telegram) < 2:
                return None
            kind, opcode = telegram[0], telegram[1]
            if kind not in (0x00, 0x80):
                log.info("fake NXT: ignoring telegram of type 0x%02x", kind)
                return None
            status, payload = self._execute(opcode, telegram)
            if kind == 0x80:
                return None
            reply = bytes([0x02, opcode, status]) + payload
            if self.faults.lost_replies > 0:
                self.faults.lost_replies -= 1
                return None
            if self.faults.garbled_replies > 0:
                self.faults.garbled_replies -= 1
                reply = bytes([reply[0] ^ 0xA5]) + reply[1:]
            return reply

    def _execute(self, opcode: int, telegram: bytes) -> tuple[int, bytes]:
        if opcode not in _LENGTHS:
            return _UNKNOWN_OPCODE, b""
        if len(telegram) != _LENGTHS[opcode]:
            return _INSANE_PACKET, b""
        if opcode == _GET_BATTERY_LEVEL:
            return _OK, struct.pack("<H", self.faults.battery_mv)
        port = telegram[2]
        if port >= len(self.outputs):
            return _BAD_OUTPUT, b""
        if opcode == _SET_OUTPUT_STATE:
            return self._set_output_state(port, telegram), b""
        if opcode == _GET_OUTPUT_STATE:
            return _OK, self._output_state(port)
        if telegram[3] not in (0, 1):
            return _OUT_OF_RANGE, b""
        if port == self.tilt_port:
            if telegram[3]:
                self._block_zero = self._motor_deg()
            else:
                self._rotation_zero = self._motor_deg()
        return _OK, b""

    def _set_output_state(self, port: int, telegram: bytes) -> int:
        power, mode, regulation, turn, run, limit = struct.unpack("<bBBbBI", telegram[3:])
        if not -100 <= power <= 100 or not -100 <= turn <= 100 or regulation > 2:
            return _OUT_OF_RANGE
        out = _Output(power, mode, regulation, turn, run, limit)
        self.outputs[port] = out
        if port == self.tilt_port:
            self._drive_tilt(out)
        elif port in self.diode_ports:
            on = bool(mode & _MOTORON) and power != 0 and run != _RUN_IDLE
            self.world.set_diode(self.diode_ports[port], on)
        return _OK

    def _output_state(self, port: int) -> bytes:
        out = self.outputs[port]
        run_state = out.run_state
        tacho = block = rotation = 0
        if port == self.tilt_port:
            motor = self._motor_deg()
            run_state = _RUN_RUNNING if self._tilt_running() else _RUN_IDLE
            tacho = round(motor)
            block = round(motor - self._block_zero)
            rotation = round(motor - self._rotation_zero)
        return struct.pack(
            "<BbBBbBIiii",
            port,
            out.power,
            out.mode,
            out.regulation,
            out.turn_ratio,
            run_state,
            out.tacho_limit,
            tacho,
            block,
            rotation,
        )
