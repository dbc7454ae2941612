"""One owner per device: an exclusive advisory lock per connection.

Two daemons driving one turntable would fight over it without either noticing.
Every driver takes a ``DeviceLock`` on its connection when it opens (a serial
port's real path, ``tcp://host:port`` plus the unit id, a USB bus address) and
releases it when it closes. The lock is ``fcntl.flock`` on a file named after
the connection in the lock folder (``$BTFRIG_LOCK_DIR``, default
``<tmp>/btfrig-locks-<uid>``); the holder writes its pid into it, so a refused
open names the process to look at. The kernel releases a dead process's lock.

``<tmp>`` is everyone's: a link planted there by another user would make the
daemon truncate whatever it points at. So the default folder is private (this
user's, writable by no one else, else refused), and a lock file is opened
without following a link and must be a plain file with one name.
"""

from __future__ import annotations

import errno
import fcntl
import os
import re
import stat
import tempfile
from pathlib import Path

from drivers.errors import DeviceError

__all__ = ["DeviceLock", "lock_dir", "serial_lock_key"]


def lock_dir() -> Path:
    """The folder of the lock files (``$BTFRIG_LOCK_DIR`` or ``<tmp>/btfrig-locks-<uid>``)."""
    folder = os.environ.get("BTFRIG_LOCK_DIR")
    return Path(folder) if folder else Path(tempfile.gettempdir()) / f"btfrig-locks-{os.geteuid()}"


def _check_private(folder: Path, *, device: str) -> None:
    """The default folder must be this user's own, writable by no one else."""
    info = os.lstat(folder)
    if stat.S_ISLNK(info.st_mode) or not stat.S_ISDIR(info.st_mode):
        why = "a symbolic link" if stat.S_ISLNK(info.st_mode) else "not a folder"
    elif info.st_uid != os.geteuid():
        why = f"owned by user id {info.st_uid}"
    elif info.st_mode & 0o022:
        why = f"writable by others (mode {stat.S_IMODE(info.st_mode):o})"
    else:
        return
    raise DeviceError(
        device,
        "open",
        f"lock folder {folder} is {why}; it must be a folder of this user's that no one else "
        "can write to: remove it, or set $BTFRIG_LOCK_DIR",
    )


def _open_lock_file(path: Path, *, device: str) -> int:
    """Open (creating) lock file ``path``, never through a link, never a file of two names."""
    try:
        fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_NONBLOCK, 0o644)
    except OSError as err:
        if err.errno != errno.ELOOP:
            raise DeviceError(device, "open", f"lock file {path}: {err.strerror}") from err
        fd = -1
    info = os.fstat(fd) if fd >= 0 else None
    if info is not None and stat.S_ISREG(info.st_mode) and info.st_nlink == 1:
        return fd
    if fd >= 0:
        os.close(fd)
    raise DeviceError(
        device,
        "open",
        f"lock file {path} is a link or not a plain file (someone else may have planted it); "
        "it was not opened: remove it and open again",
    )


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
        folder.mkdir(mode=0o700, parents=True, exist_ok=True)
        if not os.environ.get("BTFRIG_LOCK_DIR"):
            _check_private(folder, device=device)
        self.path = folder / (re.sub(r"[^A-Za-z0-9._-]+", "_", key).strip("_") + ".lock")
        fd = _open_lock_file(self.path, device=device)
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
