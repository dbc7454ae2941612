"""Pseudo-terminals as serial lines: a device node a driver opens like ``/dev/ttyUSB0``.

``RawPty`` is one pty whose slave path a driver opens while the peer reads
and writes the master. ``PtyNullModem`` joins two ptys with a relay thread,
like a null-modem cable, for peers (such as pymodbus's serial server) that
themselves want a device path to open.
"""

from __future__ import annotations

import contextlib
import os
import select
import threading
import tty

__all__ = ["PtyNullModem", "RawPty"]


class RawPty:
    """One pty in raw mode (no echo, no line editing).

    The peer keeps the slave open too, so the master never sees a hang-up
    while a driver closes and reopens the port.
    """

    def __init__(self) -> None:
        self.master, self._slave = os.openpty()
        tty.setraw(self._slave)
        self.path = os.ttyname(self._slave)

    def close(self) -> None:
        """Close both ends; idempotent."""
        for fd in (self.master, self._slave):
            with contextlib.suppress(OSError):
                os.close(fd)
        self.master = self._slave = -1


class PtyNullModem:
    """Two ptys whose masters a thread cross-connects: ``port_a`` ↔ ``port_b``.

    Bytes written to ``port_a`` come out of ``port_b`` and back. Start and
    stop explicitly (or use as a context manager); stopping joins the thread.
    """

    def __init__(self, name: str = "pty-null-modem"):
        self._a = RawPty()
        self._b = RawPty()
        self.port_a = self._a.path
        self.port_b = self._b.path
        self._wake_r, self._wake_w = os.pipe()
        self._thread = threading.Thread(target=self._relay, name=name, daemon=True)

    def start(self) -> PtyNullModem:
        self._thread.start()
        return self

    def stop(self) -> None:
        """Stop the relay, join it and close the ptys; idempotent."""
        if self._wake_w >= 0:
            os.write(self._wake_w, b"x")
        if self._thread.is_alive():
            self._thread.join(timeout=5)
        for fd in (self._wake_r, self._wake_w):
            with contextlib.suppress(OSError):
                os.close(fd)
        self._wake_r = self._wake_w = -1
        self._a.close()
        self._b.close()

    def __enter__(self) -> PtyNullModem:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()

    def _relay(self) -> None:
        peer = {self._a.master: self._b.master, self._b.master: self._a.master}
        while True:
            readable, _, _ = select.select([*peer, self._wake_r], [], [])
            if self._wake_r in readable:
                return
            for fd in readable:
                try:
                    data = os.read(fd, 4096)
                except OSError:  # EIO: no slave open right now; nothing to relay
                    continue
                os.write(peer[fd], data)
