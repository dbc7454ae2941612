"""Simulated devices that answer the drivers on the wire, all moving one ``sim.world.World``.

- ``TurntableDrivePeer``, ``LampBankPeer``: pymodbus servers (TCP on loopback
  or RTU on a pty) speaking the register maps of ``docs/devices.md``.
- ``DynamixelBusPeer``: a Protocol 2.0 bus of X-series servos on a pty.
- ``start_motion_peers``: all three at once, with ``MotionPeers.rig_config``
  pointing a rig config's connections at them.
- ``FakeNxtBrick``: the laser unit's LEGO NXT, as a pyusb backend
  (``FakeNxtUsbBackend``) or on a pty (``NxtSerialPeer``).
- ``CameraServer``: frames rendered from the world, over ZeroMQ.

Every peer has ``start()``/``stop()`` (and is a context manager), a
``faults: ReplyFaults`` for run-time reply faults, device-specific fault
setters, and takes a fault table (dict) at construction.
"""

from sim.peers._faults import ReplyFaults
from sim.peers._pty import PtyNullModem, RawPty
from sim.peers.camera_server import CameraFaults, CameraServer
from sim.peers.dynamixel import DynamixelBusPeer
from sim.peers.modbus import LampBankPeer, TurntableDrivePeer
from sim.peers.motion import MOTION_PEERS, MotionPeers, start_motion_peers
from sim.peers.nxt import FakeNxtBrick, FakeNxtUsbBackend, NxtFaults, NxtSerialPeer

__all__ = [
    "MOTION_PEERS",
    "CameraFaults",
    "CameraServer",
    "DynamixelBusPeer",
    "FakeNxtBrick",
    "FakeNxtUsbBackend",
    "LampBankPeer",
    "MotionPeers",
    "NxtFaults",
    "NxtSerialPeer",
    "PtyNullModem",
    "RawPty",
    "ReplyFaults",
    "TurntableDrivePeer",
    "start_motion_peers",
]
