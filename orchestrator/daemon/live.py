"""The workers' results, written into the session archive as they arrive.

``material/live/<stage>/<camera>/`` holds ``step`` and ``sub`` (n,) int64 and
each array the stage returned, ``(n, *shape)``: row i belongs to frame
(``step[i]``, ``sub[i]``); rows are in the order the results came in. Workers
name arrays ``<stage>.<name>``; one frame may carry several stages.

A writer thread per session appends them in small batches — a stage and
camera's rows once 32 of them or 4 MB wait, everything at least once a second,
and all when the session drains — so a crash loses at most the last second's
results, and one append per array per batch keeps the writes few. The
daemon's loop never waits on the disk: it hands results over and stops taking
new frames from the session while more than ``max_backlog_bytes`` wait
(:attr:`LiveWriter.backlogged`), so memory stays bounded however long the
session. ``step`` is appended last, so a row is complete once ``step`` has it;
the rows an interrupted batch left in the other arrays are cut off when the
group is next opened for writing (a resumed session).
"""

from __future__ import annotations

import queue
import threading
import time
from collections.abc import Mapping

import numpy as np

__all__ = ["LiveWriter"]

_BATCH_ROWS = 32
_BATCH_BYTES = 4 << 20
_FLUSH_EVERY_S = 1.0  # nothing waits longer to be written
_CHUNK_BYTES = 1 << 16  # rows per chunk: about this many bytes, at least one row
_CLOSE = object()


class LiveWriter:
    """Appends one session's live results to ``material/live`` of its archive.

    ``material`` is the archive's writable ``material/`` zarr group (opened on
    the first batch, so a session without workers writes nothing). Call
    :meth:`finish` (without waiting) or :meth:`close` to write what is left and
    stop the thread.
    """

    def __init__(self, material, *, max_backlog_bytes: int = 16 << 20):
        self._material = material
        self.max_backlog_bytes = max_backlog_bytes
        self._live = None
        self._arrays: dict[tuple[str, str], dict] = {}
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
        ids = {"sub": np.int64(header["sub"]), "step": np.int64(header["step"])}
        rows: dict[tuple[str, str], dict[str, np.ndarray]] = {}
        for full, value in arrays.items():
            stage, _, name = full.partition(".")
            row = rows.setdefault((stage, str(header["camera"])), dict(ids))
            row[name] = np.array(value)  # a copy: the message buffer goes back to the socket
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
            for row in rows[1:]:
                if row.keys() != rows[0].keys():
                    raise ValueError(
                        f"step {row['step']} returned {sorted(row)}, step {rows[0]['step']} "
                        f"{sorted(rows[0])}; a stage returns the same arrays for every frame"
                    )
            arrays = self._group(*key, rows[0])
            names = [n for n in rows[0] if n not in ("sub", "step")]
            for name in (*names, "sub", "step"):  # step last: the commit
                arrays[name].append(np.stack([row[name] for row in rows]))
        except (OSError, ValueError) as err:  # a full disk, a stage that changed its arrays
            with self._lock:
                self._errors.append(f"live/{key[0]}/{key[1]}: {len(rows)} row(s) lost: {err}")
        finally:
            with self._lock:
                self._backlog -= _nbytes(rows)

    def _group(self, stage: str, camera: str, example: Mapping[str, np.ndarray]) -> dict:
        """The arrays of ``live/<stage>/<camera>``, created or cut back to ``len(step)``."""
        arrays = self._arrays.get((stage, camera))
        if arrays is None:
            if self._live is None:
                self._live = self._material.require_group("live")
            group = self._live.require_group(stage).require_group(camera)
            arrays = dict(group.arrays())
            rows = arrays["step"].shape[0] if "step" in arrays else 0
            for array in arrays.values():
                if array.shape[0] != rows:  # a batch a crash interrupted
                    array.resize((rows, *array.shape[1:]))
            self._arrays[(stage, camera)] = arrays
        rows = arrays["step"].shape[0] if "step" in arrays else 0
        for name, value in example.items():
            if name not in arrays:  # a new array starts with zero rows for the older frames
                per_chunk = max(1, _CHUNK_BYTES // max(1, value.nbytes))
                arrays[name] = self._live[stage][camera].create_array(
                    name,
                    shape=(rows, *value.shape),
                    chunks=(per_chunk, *value.shape),
                    dtype=value.dtype,
                )
        return arrays


def _nbytes(rows: list[dict[str, np.ndarray]]) -> int:
    return sum(v.nbytes for row in rows for v in row.values())
