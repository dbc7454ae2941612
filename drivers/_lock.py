"""One owner per device: an exclusive advisory lock per connection.

Two daemons driving one turntable would fight over it without either noticing.
Every driver takes a ``DeviceLock`` on its connection when it opens (a serial
port's real path, ``tcp://host:port`` plus the unit id, a USB bus address) and
releases it when it closes. The lock is ``fcntl.flock`` on a file named after
the connection in the lock folder (``$BTFRIG_LOCK_DIR``, default
``<tmp>/btfrig-locks``); the holder writes its pid into it, so a refused open
names the process to look at. The kernel releases a dead process's lock.
"""

from __future__ import annotations

import fcntl
import os
import re
import tempfile
from pathlib import Path

from drivers.errors import DeviceError

__all__ = ["DeviceLock", "lock_dir", "serial_lock_key"]


def lock_dir() -> Path:
    """The folder of the lock files (``$BTFRIG_LOCK_DIR`` or ``<tmp>/btfrig-locks``)."""
    return Path(os.environ.get("BTFRIG_LOCK_DIR") or Path(tempfile.gettempdir()) / "btfrig-locks")


def serial_lock_key(port: str) -> str:
    """The lock key of a serial port: its real path, so two names of one port collide."""
    return f"serial:{os.path.realpath(port)}"


class DeviceLock:
    """An exclusive lock on ``key`` held by this process until :meth:`release`.

    Raises ``DeviceError`` naming ``device``, the connection and the holder's
    pid when another open (in this process or another) holds it.
    """

    def __init__(self, key: str, *, device: str):
        self.key = key
        folder = lock_dir()
        folder.mkdir(parents=True, exist_ok=True)
        self.path = folder / (re.sub(r"[^A-Za-z0-9._-]+", "_", key).strip("_") + ".lock")
        fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o666)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.pread(fd, 32, 0).decode(errors="replace").strip() or "unknown"
            os.close(fd)
            raise DeviceError(
                device,
                "open",
                f"{key} is in use by process {holder} (lock {self.path}); "
                "stop that daemon or point this config at another device",
            ) from None
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
        self._fd: int | None = fd

    def release(self) -> None:
        """Give the device up; idempotent."""
        fd, self._fd = self._fd, None
        if fd is not None:
            os.ftruncate(fd, 0)
            fcntl.flock(fd, fcntl.LOCK_UN)
            os.close(fd)
