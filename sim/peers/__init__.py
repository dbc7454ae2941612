"""Simulated devices that answer the drivers on the wire, all moving one ``sim.world.World``.

- ``start_peer(role, section, world)`` starts the peer of a device section's
  ``kind`` (``sim.peers.registry``); ``peer.connect(section)`` points the
  section's device at it, so unchanged drivers reach it.
- ``TurntableDrivePeer``, ``LampBankPeer``: pymodbus servers (TCP on loopback
  or RTU on a pty) speaking the register maps of ``docs/devices.md``.
- ``DynamixelBusPeer``: a Protocol 2.0 bus of X-series servos on a pty.
- ``FakeNxtBrick``: the laser unit's LEGO NXT, as a pyusb backend
  (``FakeNxtUsbBackend``) or on a pty (``NxtSerialPeer``).
- ``CameraServer``: frames rendered from the world, over ZeroMQ.
- ``UrControllerPeer``: a Universal Robots arm controller (dashboard and
  real-time interface on loopback TCP ports).

Every peer has ``start()``/``stop()`` (and is a context manager), a
``faults: ReplyFaults`` for run-time reply faults, device-specific fault
setters, and takes a fault table (dict) at construction.
"""

from sim.peers._faults import ReplyFaults
from sim.peers._pty import PtyNullModem, RawPty
from sim.peers.camera_server import CameraFaults, CameraServer
from sim.peers.dynamixel import DynamixelBusPeer
from sim.peers.modbus import LampBankPeer, TurntableDrivePeer
from sim.peers.nxt import FakeNxtBrick, FakeNxtUsbBackend, NxtFaults, NxtSerialPeer
from sim.peers.registry import Peer, register_peer, start_peer
from sim.peers.ur import UrControllerPeer

__all__ = [
    "CameraFaults",
    "CameraServer",
    "DynamixelBusPeer",
    "FakeNxtBrick",
    "FakeNxtUsbBackend",
    "LampBankPeer",
    "NxtFaults",
    "NxtSerialPeer",
    "Peer",
    "PtyNullModem",
    "RawPty",
    "ReplyFaults",
    "TurntableDrivePeer",
    "UrControllerPeer",
    "register_peer",
    "start_peer",
]
