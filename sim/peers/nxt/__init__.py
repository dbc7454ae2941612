"""A fake LEGO NXT brick (the laser unit's controller), reachable over USB or serial.

``FakeNxtBrick(world)`` answers direct-command telegrams and moves the world's
laser; ``FakeNxtUsbBackend(brick)`` is a pyusb backend that finds it;
``NxtSerialPeer(brick)`` serves it on a pty (``.port``) with Bluetooth framing.
"""

from sim.peers.nxt._brick import FakeNxtBrick, NxtFaults
from sim.peers.nxt._serial import NxtSerialPeer
from sim.peers.nxt._usb import FakeNxtUsbBackend

__all__ = ["FakeNxtBrick", "FakeNxtUsbBackend", "NxtFaults", "NxtSerialPeer"]
