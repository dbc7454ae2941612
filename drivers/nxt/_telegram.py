"""LEGO NXT direct-command telegrams: pure bytes in, bytes out.

From the LEGO MINDSTORMS NXT Bluetooth Developer Kit, Appendix 2 ("Direct
Commands"). A telegram is ``[command type, opcode, payload...]``; the command
type is 0x00 (direct command, reply required) or 0x80 (direct command, no
reply); a reply is ``[0x02, opcode, status, payload...]`` with status 0x00 on
success. Multi-byte fields are little-endian. Transport framing (the Bluetooth
2-byte length prefix; none on USB) is not part of a telegram.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from enum import IntEnum, IntFlag

__all__ = [
    "MOTOR_PORTS",
    "STATUS_MESSAGES",
    "Opcode",
    "OutputMode",
    "OutputState",
    "RegulationMode",
    "RunState",
    "TelegramError",
    "decode_battery_level",
    "decode_output_state",
    "decode_status",
    "encode_get_battery_level",
    "encode_get_output_state",
    "encode_reset_motor_position",
    "encode_set_output_state",
]

DIRECT_REPLY = 0x00
DIRECT_NO_REPLY = 0x80
REPLY = 0x02

MOTOR_PORTS = {"A": 0, "B": 1, "C": 2}


class Opcode(IntEnum):
    SET_OUTPUT_STATE = 0x04
    GET_OUTPUT_STATE = 0x06
    RESET_MOTOR_POSITION = 0x0A
    GET_BATTERY_LEVEL = 0x0B


class OutputMode(IntFlag):
    COAST = 0x00
    MOTORON = 0x01
    BRAKE = 0x02
    REGULATED = 0x04


class RegulationMode(IntEnum):
    IDLE = 0x00
    MOTOR_SPEED = 0x01
    MOTOR_SYNC = 0x02


class RunState(IntEnum):
    IDLE = 0x00
    RAMPUP = 0x10
    RUNNING = 0x20
    RAMPDOWN = 0x40


# The brick's status byte (Appendix 2, "Error messages"); 0x00 is success.
STATUS_MESSAGES = {
    0x20: "pending communication transaction in progress",
    0x40: "specified mailbox queue is empty",
    0xBD: "request failed",
    0xBE: "unknown command opcode",
    0xBF: "insane packet",
    0xC0: "data contains out-of-range values",
    0xDD: "communication bus error",
    0xDE: "no free memory in communication buffer",
    0xDF: "specified channel/connection is not valid",
    0xE0: "specified channel/connection not configured or busy",
    0xEC: "no active program",
    0xED: "illegal size specified",
    0xEE: "illegal mailbox queue id specified",
    0xEF: "attempted to access invalid field of a structure",
    0xF0: "bad input or output specified",
    0xFB: "insufficient memory available",
    0xFF: "bad arguments",
}

_U32_MAX = 0xFFFFFFFF
_OUTPUT_STATE = struct.Struct("<BBBBbBBbBIiii")  # the 25-byte GETOUTPUTSTATE reply


class TelegramError(ValueError):
    """A telegram could not be encoded, or a reply is malformed or reports an error.

    ``malformed`` is True for a garbled reply (wrong length, type or opcode), which
    is worth asking again; False for a valid reply whose status is an error.
    """

    def __init__(self, message: str, *, malformed: bool, status: int | None = None):
        super().__init__(message)
        self.malformed = malformed
        self.status = status


@dataclass(frozen=True)
class OutputState:
    """One output port as GETOUTPUTSTATE reports it (counts are motor degrees)."""

    port: int
    power: int
    mode: OutputMode
    regulation: RegulationMode
    turn_ratio: int
    run_state: int
    tacho_limit: int
    tacho_count: int
    block_tacho_count: int
    rotation_count: int


def _check_port(port: int) -> None:
    if port not in MOTOR_PORTS.values():
        raise TelegramError(
            f"output port {port} is not valid; valid are 0, 1, 2 (A, B, C)", malformed=False
        )


def _command_type(reply: bool) -> int:
    return DIRECT_REPLY if reply else DIRECT_NO_REPLY


def encode_set_output_state(
    port: int,
    *,
    power: int,
    mode: OutputMode,
    regulation: RegulationMode,
    turn_ratio: int = 0,
    run_state: RunState,
    tacho_limit: int = 0,
    reply: bool = True,
) -> bytes:
    """SETOUTPUTSTATE (0x04): 12 bytes. ``tacho_limit`` 0 runs forever."""
    _check_port(port)
    if not -100 <= power <= 100:
        raise TelegramError(f"power {power} is out of range; valid is -100..100", malformed=False)
    if not -100 <= turn_ratio <= 100:
        raise TelegramError(
            f"turn_ratio {turn_ratio} is out of range; valid is -100..100", malformed=False
        )
    if not 0 <= tacho_limit <= _U32_MAX:
        raise TelegramError(
            f"tacho_limit {tacho_limit} is out of range; valid is 0..{_U32_MAX}", malformed=False
        )
    return struct.pack(
        "<BBBbBBbBI",
        _command_type(reply),
        Opcode.SET_OUTPUT_STATE,
        port,
        power,
        int(mode),
        int(regulation),
        turn_ratio,
        int(run_state),
        tacho_limit,
    )


def encode_get_output_state(port: int) -> bytes:
    """GETOUTPUTSTATE (0x06): 3 bytes (a reply is always required)."""
    _check_port(port)
    return bytes([DIRECT_REPLY, Opcode.GET_OUTPUT_STATE, port])


def encode_reset_motor_position(port: int, *, relative: bool, reply: bool = True) -> bytes:
    """RESETMOTORPOSITION (0x0A): 4 bytes.

    ``relative`` True resets the block tacho count (position relative to the
    last movement), False the rotation count (the absolute position).
    """
    _check_port(port)
    return bytes([_command_type(reply), Opcode.RESET_MOTOR_POSITION, port, int(relative)])


def encode_get_battery_level() -> bytes:
    """GETBATTERYLEVEL (0x0B): 2 bytes."""
    return bytes([DIRECT_REPLY, Opcode.GET_BATTERY_LEVEL])


def decode_status(reply: bytes, opcode: Opcode, *, length: int = 3) -> bytes:
    """Check a reply's framing and status byte; return its payload after the status.

    Raises ``TelegramError`` (``malformed=True``) for a wrong length, reply type
    or opcode, and (``malformed=False``) for a non-zero status.
    """
    if len(reply) != length:
        raise TelegramError(
            f"reply to {opcode.name} has {len(reply)} bytes, expected {length}: {reply.hex(' ')}",
            malformed=True,
        )
    if reply[0] != REPLY or reply[1] != opcode:
        raise TelegramError(
            f"reply to {opcode.name} starts {reply[:2].hex(' ')}, "
            f"expected 02 {int(opcode):02x}: {reply.hex(' ')}",
            malformed=True,
        )
    status = reply[2]
    if status != 0:
        meaning = STATUS_MESSAGES.get(status, "unknown status")
        raise TelegramError(
            f"brick answered {opcode.name} with status 0x{status:02x} ({meaning})",
            malformed=False,
            status=status,
        )
    return reply[3:]


def decode_output_state(reply: bytes) -> OutputState:
    """The 25-byte GETOUTPUTSTATE reply."""
    decode_status(reply, Opcode.GET_OUTPUT_STATE, length=_OUTPUT_STATE.size)
    (_, _, _, port, power, mode, regulation, turn, run, limit, tacho, block, rotation) = (
        _OUTPUT_STATE.unpack(reply)
    )
    try:
        regulation_mode = RegulationMode(regulation)
    except ValueError:
        raise TelegramError(
            f"GET_OUTPUT_STATE reply has regulation mode {regulation}, valid are 0, 1, 2",
            malformed=True,
        ) from None
    return OutputState(
        port=port,
        power=power,
        mode=OutputMode(mode),
        regulation=regulation_mode,
        turn_ratio=turn,
        run_state=run,
        tacho_limit=limit,
        tacho_count=tacho,
        block_tacho_count=block,
        rotation_count=rotation,
    )


def decode_battery_level(reply: bytes) -> int:
    """The 5-byte GETBATTERYLEVEL reply → millivolts."""
    payload = decode_status(reply, Opcode.GET_BATTERY_LEVEL, length=5)
    return struct.unpack("<H", payload)[0]
