"""The workers' results, written into the session archive as they arrive.

They go to ``material/live/<stage>/<camera>/`` in the material format's layout
(``rig.material``: :func:`~rig.material.live_rows`, :class:`~rig.material.LiveAppender`,
read back with :func:`~rig.material.read_live`); rows in the order the results came in.

A writer thread per session appends them in small batches — a stage and
camera's rows once 32 of them or 4 MB wait, everything at least once a second,
and all when the session drains — so a crash loses at most the last second's
results, and one append per array per batch keeps the writes few. The
daemon's loop never waits on the disk: it hands results over and stops taking
new frames from the session while more than ``max_backlog_bytes`` wait
(:attr:`LiveWriter.backlogged`), so memory stays bounded however long the
session.
"""

from __future__ import annotations

import queue
import threading
import time
from collections.abc import Mapping

import numpy as np

from rig.material import LiveAppender, MaterialError, live_rows

__all__ = ["LiveWriter"]

_BATCH_ROWS = 32
_BATCH_BYTES = 4 << 20
_FLUSH_EVERY_S = 1.0  # nothing waits longer to be written
_CLOSE = object()


class LiveWriter:
    """Appends one session's live results to ``material/live`` of its archive.

    ``material`` is the archive's writable ``material/`` zarr group (opened on
    the first batch, so a session without workers writes nothing). Call
    :meth:`finish` (without waiting) or :meth:`close` to write what is left and
    stop the thread.
    """

    def __init__(self, material, *, max_backlog_bytes: int = 16 << 20):
        self._appender = LiveAppender(material)
        self.max_backlog_bytes = max_backlog_bytes
        self._waiting: dict[tuple[str, str], list[dict[str, np.ndarray]]] = {}
        self._inbox: queue.SimpleQueue = queue.SimpleQueue()
        self._lock = threading.Lock()
        self._backlog = 0  # bytes handed over and not written yet
        self._errors: list[str] = []
        self._thread: threading.Thread | None = None
        self._closing = False
        self.frames = 0  # frames with results handed over

    @property
    def backlogged(self) -> bool:
        """More than ``max_backlog_bytes`` wait to be written."""
        with self._lock:
            return self._backlog > self.max_backlog_bytes

    def append(self, header: Mapping, arrays: Mapping[str, np.ndarray]) -> None:
        """Hand over one frame's results; ``header`` has its ``step``, ``sub`` and ``camera``."""
        try:
            rows = live_rows(header, arrays)  # copies: the message buffer goes back to the socket
        except MaterialError as err:
            with self._lock:
                self._errors.append(f"step {header['step']} sub {header['sub']}: {err}")
            return
        if not rows:
            return
        with self._lock:
            self._backlog += _nbytes(list(rows.values()))
        if self._thread is None:
            self._thread = threading.Thread(target=self._run, name="live-writer", daemon=True)
            self._thread.start()
        self._inbox.put(list(rows.items()))
        self.frames += 1

    def take_errors(self) -> list[str]:
        """What failed to be written since the last call (the daemon reports it)."""
        with self._lock:
            errors, self._errors = self._errors, []
        return errors

    def finish(self) -> bool:
        """Ask the thread to write everything handed over and stop; whether it has."""
        if self._thread is None:
            return True
        if not self._closing:
            self._closing = True
            self._inbox.put(_CLOSE)
        if self._thread.is_alive():
            return False
        self._thread.join()
        self._thread = None
        return True

    def close(self) -> None:
        """Write everything handed over, then stop the thread (waits for it)."""
        self.finish()
        if self._thread is not None:
            self._thread.join()
            self._thread = None

    def _run(self) -> None:
        written = time.monotonic()
        while True:
            try:
                item = self._inbox.get(timeout=_FLUSH_EVERY_S)
            except queue.Empty:
                item = None
            if item is _CLOSE:
                self._write_all()
                return
            for key, row in item or ():
                waiting = self._waiting.setdefault(key, [])
                waiting.append(row)
                if len(waiting) >= _BATCH_ROWS or _nbytes(waiting) >= _BATCH_BYTES:
                    self._write(key)
            if time.monotonic() - written >= _FLUSH_EVERY_S:
                self._write_all()
                written = time.monotonic()

    def _write_all(self) -> None:
        for key in list(self._waiting):
            self._write(key)

    def _write(self, key: tuple[str, str]) -> None:
        rows = self._waiting.pop(key)
        try:
            self._appender.append(*key, rows)
        except (OSError, ValueError) as err:  # a full disk, a stage that changed its arrays
            with self._lock:
                self._errors.append(f"live/{key[0]}/{key[1]}: {len(rows)} row(s) lost: {err}")
        finally:
            with self._lock:
                self._backlog -= _nbytes(rows)


def _nbytes(rows: list[dict[str, np.ndarray]]) -> int:
    return sum(v.nbytes for row in rows for v in row.values())
