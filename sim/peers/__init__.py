"""Simulated devices that answer the drivers on the wire, all moving one ``sim.world.World``.

- ``TurntableDrivePeer``, ``LampBankPeer``: pymodbus servers (TCP on loopback
  or RTU on a pty) speaking the register maps of ``docs/devices.md``.
- ``DynamixelBusPeer``: a Protocol 2.0 bus of X-series servos on a pty.
- ``start_motion_peers``: all three at once, with ``MotionPeers.rig_config``
  pointing a rig config's connections at them.

Every peer has ``start()``/``stop()`` (and is a context manager), a
``faults: ReplyFaults`` for run-time reply faults, device-specific fault
setters, and takes a fault table (dict) at construction.
"""

from sim.peers._faults import ReplyFaults
from sim.peers._pty import PtyNullModem, RawPty
from sim.peers.dynamixel import DynamixelBusPeer
from sim.peers.modbus import LampBankPeer, TurntableDrivePeer
from sim.peers.motion import MOTION_PEERS, MotionPeers, start_motion_peers

__all__ = [
    "MOTION_PEERS",
    "DynamixelBusPeer",
    "LampBankPeer",
    "MotionPeers",
    "PtyNullModem",
    "RawPty",
    "ReplyFaults",
    "TurntableDrivePeer",
    "start_motion_peers",
]
