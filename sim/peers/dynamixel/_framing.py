"""Dynamixel Protocol 2.0 packets, written from the ROBOTIS e-manual.

An instruction or status packet is::

    FF FF FD 00 | ID | LEN_L LEN_H | INST | PARAM… | CRC_L CRC_H

``LEN`` counts INST, the (stuffed) parameters and the CRC. Inside INST and
the parameters any ``FF FF FD`` is sent as ``FF FF FD FD`` (byte stuffing) so
that a header never appears in the body. The CRC is CRC-16 with polynomial
0x8005 (not reflected, initial value 0), over everything from the header to
the last stuffed parameter, sent low byte first. A status packet's INST is
0x55, followed by an error byte (bit 7: hardware alert; 1–7: the error
numbers in ``ERRORS``) and the parameters.

References
----------
ROBOTIS e-manual, "DYNAMIXEL Protocol 2.0" (packet, CRC, byte stuffing).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

__all__ = [
    "BROADCAST_ID",
    "ERRORS",
    "HEADER",
    "Instruction",
    "Packet",
    "PacketReader",
    "crc16",
    "encode",
    "encode_status",
    "stuff",
    "unstuff",
]

HEADER = b"\xff\xff\xfd\x00"
BROADCAST_ID = 0xFE
STATUS = 0x55
ALERT = 0x80
ERRORS = {
    1: "result fail",
    2: "instruction error",
    3: "CRC error",
    4: "data range error",
    5: "data length error",
    6: "data limit error",
    7: "access error",
}
_MAX_LENGTH = 1024  # longer bodies are noise, not packets


class Instruction:
    PING = 0x01
    READ = 0x02
    WRITE = 0x03
    REBOOT = 0x08
    SYNC_READ = 0x82
    SYNC_WRITE = 0x83


def _crc_table() -> tuple[int, ...]:
    table = []
    for byte in range(256):
        crc = byte << 8
        for _ in range(8):
            crc = (crc << 1) ^ 0x8005 if crc & 0x8000 else crc << 1
        table.append(crc & 0xFFFF)
    return tuple(table)


_CRC_TABLE = _crc_table()


def crc16(data: bytes) -> int:
    """CRC-16/0x8005 of ``data`` as Protocol 2.0 computes it."""
    crc = 0
    for byte in data:
        crc = ((crc << 8) ^ _CRC_TABLE[((crc >> 8) ^ byte) & 0xFF]) & 0xFFFF
    return crc


def stuff(body: bytes) -> bytes:
    """Insert 0xFD after every ``FF FF FD`` in a packet body."""
    return body.replace(b"\xff\xff\xfd", b"\xff\xff\xfd\xfd")


def unstuff(body: bytes) -> bytes:
    """Undo ``stuff``."""
    return body.replace(b"\xff\xff\xfd\xfd", b"\xff\xff\xfd")


def encode(servo_id: int, instruction: int, params: bytes = b"") -> bytes:
    """A complete packet: header, id, length, stuffed body, CRC."""
    if not 0 <= servo_id <= 0xFE:
        raise ValueError(f"servo id {servo_id} outside 0..254")
    body = stuff(bytes([instruction]) + bytes(params))
    length = len(body) + 2
    frame = HEADER + bytes([servo_id, length & 0xFF, length >> 8]) + body
    return frame + crc16(frame).to_bytes(2, "little")


def encode_status(servo_id: int, error: int, params: bytes = b"") -> bytes:
    """A status packet (INST 0x55) with ``error`` and ``params``."""
    return encode(servo_id, STATUS, bytes([error]) + bytes(params))


@dataclass(frozen=True)
class Packet:
    """A received packet; ``crc_ok`` false means it must be answered with a CRC error."""

    servo_id: int
    instruction: int
    params: bytes
    crc_ok: bool = True


class PacketReader:
    """Cut a byte stream into packets, skipping noise before a header."""

    def __init__(self) -> None:
        self._buffer = bytearray()

    def feed(self, data: bytes) -> Iterator[Packet]:
        """Add received bytes; yield every packet now complete."""
        self._buffer += data
        while True:
            start = self._buffer.find(HEADER)
            if start < 0:
                # keep a possible partial header at the end
                del self._buffer[: max(0, len(self._buffer) - 3)]
                return
            del self._buffer[:start]
            if len(self._buffer) < 7:
                return
            length = int.from_bytes(self._buffer[5:7], "little")
            if not 3 <= length <= _MAX_LENGTH:
                del self._buffer[:1]  # not a packet: look for the next header
                continue
            total = 7 + length
            if len(self._buffer) < total:
                return
            frame = bytes(self._buffer[:total])
            del self._buffer[:total]
            body = unstuff(frame[7:-2])
            crc_ok = crc16(frame[:-2]) == int.from_bytes(frame[-2:], "little")
            yield Packet(frame[4], body[0], body[1:], crc_ok)
