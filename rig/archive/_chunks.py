"""Writing a step's frames: chunk files compressed in parallel, on disk before the commit.

``StepChunks.write`` checks each frame against its camera's format, gives each
chunk its frame's own record, compresses and writes the step's chunks on a
thread pool (zstd releases the GIL) and ``fsync``-s them and their folders, so
the journal's commit record, written after, never names a chunk that is not on
disk. A failure (a full disk) removes the chunks written so far: they were
never committed, and the retry needs their space.

The arrays' declared shapes grow geometrically ahead of the frames and are
trimmed to the committed frames on close; the journal, not the shape, says
which frames exist, so growing a shape is not part of a commit.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from concurrent.futures import ThreadPoolExecutor, wait
from pathlib import Path

import numpy as np

from rig.archive._errors import os_failure
from rig.archive._frames import FrameArray, chunk_record
from rig.archive._layout import Layout
from rig.archive._records import FrameRecord, StepRecord
from rig.archive._store import array_document, fsync_dir, write_atomic

__all__ = ["StepChunks"]

_MIN_CAPACITY = 64


class StepChunks:
    """The chunk files of the archive at ``path`` (its ``layout`` as read), written by
    ``workers`` threads (None: up to 8, one per CPU)."""

    def __init__(self, path: Path, layout: Layout, *, fsync: bool, workers: int | None):
        self.path = path
        self._cameras = layout.cameras
        self._arrays = layout.arrays
        self._capacity = layout.capacity
        self._zstd_level = layout.attributes["zstd_level"]
        self._fsync = fsync
        self._workers = workers or min(8, os.cpu_count() or 1)
        self._pool: ThreadPoolExecutor | None = None

    def write(
        self,
        step: StepRecord,
        records: Mapping[str, Sequence[FrameRecord]],
        next_position: Mapping[str, int],
    ) -> dict[str, list[list]]:
        """Write (and ``fsync``) every frame of ``step``, camera by camera from its
        ``next_position``; the journal's rows: ``[sub, exposure_s, timestamp, position,
        nbytes]`` per frame and camera."""
        jobs = []
        rows: dict[str, list[list]] = {}
        counts = {camera: len(records[camera]) for camera in step.cameras}
        for camera in step.cameras:
            array = self._arrays[camera]
            rows[camera] = []
            for position, record in enumerate(records[camera], next_position[camera]):
                where = f"{self.path}: step {step.index}, camera {camera!r}, sub {record.sub}"
                image = array.check_image(record.image, where=where)
                row = [int(record.sub), float(record.exposure_s), float(record.timestamp)]
                own = {"step": step.to_json(), "camera": camera, "frames": counts}
                own.update(sub=row[0], exposure_s=row[1], timestamp=row[2], position=position)
                jobs.append((array, position, image, chunk_record(own)))
                rows[camera].append([*row, position])
        self._write_chunks(step, jobs, rows, next_position)
        return rows

    def _write_chunks(
        self, step: StepRecord, jobs: list, rows: dict[str, list[list]], next_position
    ) -> None:
        """Write every chunk of ``step``; append each one's size to its row.

        On a failure the chunk files written so far are removed.
        """
        try:
            for camera, camera_rows in rows.items():
                self._ensure_capacity(camera, camera_rows[-1][3] + 1)
            futures = [self._executor().submit(self._write_chunk, job) for job in jobs]
            wait(futures)  # all of them, so none is still writing when we clean up
            sizes = [future.result() for future in futures]
            if self._fsync:
                for camera in step.cameras:
                    fsync_dir(self._arrays[camera].directory)
        except OSError as err:
            for array, position, _, _ in jobs:
                array.path(position).unlink(missing_ok=True)
            needed = sum(array.format.nbytes for array, *_ in jobs)
            where = Path(err.filename) if err.filename else self.path
            doing = f"step {step.index}'s {len(jobs)} frames"
            raise os_failure(err, where, doing=doing, needed_bytes=needed) from err
        for (array, position, _, _), nbytes in zip(jobs, sizes, strict=True):
            rows[array.camera][position - next_position[array.camera]].append(nbytes)

    def _write_chunk(self, job: tuple[FrameArray, int, np.ndarray, bytes]) -> int:
        array, position, image, record = job
        return array.write(position, image, record, fsync=self._fsync)

    def _executor(self) -> ThreadPoolExecutor:
        if self._pool is None:
            self._pool = ThreadPoolExecutor(self._workers, thread_name_prefix="archive-zstd")
        return self._pool

    def _ensure_capacity(self, camera: str, length: int) -> None:
        if length > self._capacity[camera]:
            capacity = max(length, 2 * self._capacity[camera], _MIN_CAPACITY)
            self._write_shape(camera, capacity)

    def _write_shape(self, camera: str, length: int, *, then: str = "resume") -> None:
        doc = array_document(self._cameras[camera], length=length, zstd_level=self._zstd_level)
        path = self._arrays[camera].directory / "zarr.json"
        try:
            write_atomic(path, doc, fsync=self._fsync)
        except OSError as err:
            doing = f"camera {camera!r}'s array shape ({length} frames)"
            raise os_failure(err, path, doing=doing, needed_bytes=len(doc), then=then) from err
        self._capacity[camera] = length

    def trim(self, committed: Mapping[str, int]) -> None:
        """Shrink each camera array's declared shape to its ``committed`` frames.

        Raises ArchiveFull naming the file and the space when the disk is full;
        the frames are all committed, and the next writable open trims again.
        """
        for camera, length in committed.items():
            if self._capacity[camera] != length:
                self._write_shape(
                    camera,
                    length,
                    then="open it for writing again (`rig process` does) to finish its close",
                )

    def close(self) -> None:
        """Stop the thread pool (after the writes in progress)."""
        if self._pool is not None:
            self._pool.shutdown(wait=True)
            self._pool = None
