"""A simulated Dynamixel Protocol 2.0 bus on a pty, and its packet framing."""

from sim.peers.dynamixel._framing import PacketReader, crc16, encode, encode_status
from sim.peers.dynamixel._servo import HARDWARE_ERRORS, SimServo, Table
from sim.peers.dynamixel.bus import DynamixelBusPeer

__all__ = [
    "HARDWARE_ERRORS",
    "DynamixelBusPeer",
    "PacketReader",
    "SimServo",
    "Table",
    "crc16",
    "encode",
    "encode_status",
]
