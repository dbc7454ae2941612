"""The fake NXT brick as a Bluetooth serial peer on a pty.

The Bluetooth serial-port profile carries each telegram behind a 2-byte
little-endian length. The peer opens a pty pair, answers on the master side
from a thread, and hands out the slave's path (``port``) for the driver to
open like ``/dev/rfcomm0``. A frame whose length is 0 or over 64 bytes cannot
be a telegram: the peer drops what it has buffered and resynchronises.
"""

from __future__ import annotations

import logging
import os
import select
import struct
import threading
from collections.abc import Mapping
from dataclasses import fields
from typing import Any

from rig.config import Laser
from sim.peers._faults import check_fault_keys
from sim.peers._pty import RawPty
from sim.peers.nxt._brick import FakeNxtBrick, NxtFaults
from sim.peers.registry import register_peer
from sim.world import World

__all__ = ["NxtSerialPeer"]

log = logging.getLogger(__name__)

_MAX_TELEGRAM = 64


class NxtSerialPeer:
    """Serve ``brick`` on a fresh pty until ``stop``; use as a context manager."""

    def __init__(self, brick: FakeNxtBrick):
        self.brick = brick
        self._pty = RawPty()
        self._master = self._pty.master
        self.port = self._pty.path
        self._wake_r, self._wake_w = os.pipe()
        self._thread = threading.Thread(target=self._serve, name="nxt-serial-peer", daemon=True)
        self._thread.start()

    def __enter__(self) -> NxtSerialPeer:
        return self

    def __exit__(self, *exc) -> None:
        self.stop()

    def _serve(self) -> None:
        buffer = b""
        while True:
            readable, _, _ = select.select([self._master, self._wake_r], [], [])
            if self._wake_r in readable:
                return
            try:
                buffer += os.read(self._master, 4096)
            except OSError as err:  # the slave side went away
                log.info("fake NXT serial peer: read failed (%s); stopping", err)
                return
            buffer = self._answer(buffer)

    def _answer(self, buffer: bytes) -> bytes:
        while len(buffer) >= 2:
            (length,) = struct.unpack("<H", buffer[:2])
            if not 0 < length <= _MAX_TELEGRAM:
                log.warning(
                    "fake NXT: bad length prefix %d; dropping %d bytes", length, len(buffer)
                )
                return b""
            if len(buffer) < 2 + length:
                return buffer
            telegram, buffer = buffer[2 : 2 + length], buffer[2 + length :]
            reply = self.brick.handle(telegram)
            if reply is not None:
                os.write(self._master, struct.pack("<H", len(reply)) + reply)
        return buffer

    def connect(self, section):
        """``section`` with its NXT device on this pty (Bluetooth SPP framing)."""
        device = section.device.model_copy(update={"transport": "serial", "serial_port": self.port})
        return section.model_copy(update={"device": device})

    def stop(self) -> None:
        """Stop the thread and close the pty (idempotent)."""
        if self._wake_w < 0:
            return
        os.write(self._wake_w, b"x")
        self._thread.join(timeout=5)
        for fd in (self._wake_r, self._wake_w):
            os.close(fd)
        self._wake_w = -1
        self._pty.close()


@register_peer("laser", "nxt")
def start_brick(
    section: Laser, world: World, *, faults: Mapping[str, Any], serial: bool
) -> NxtSerialPeer:
    """The laser unit's brick (``NxtFaults`` fields as the fault table) on a pty.

    Always serial: a pty is the one link a driver in another process can open
    (the USB fake is a pyusb backend, in-process only).
    """
    check_fault_keys("laser brick", faults, {field.name for field in fields(NxtFaults)})
    return NxtSerialPeer(FakeNxtBrick(world, faults=NxtFaults(**faults)))
