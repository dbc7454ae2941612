"""The session archive: one Zarr v3 directory per measurement session.

Layout (``docs/archive.md`` describes it and the commit protocol)::

    session.zarr/
      zarr.json              root group; attributes: format, cameras, plan,
                             rig_config, software versions
      frames/<camera>/       (n, H, W, C) array, one frame per chunk, zstd;
                             each chunk file ends with its frame's record
      calibration/zarr.json  group; attributes mirror the current calibration
      material/              processing results (zarr groups/arrays)
      log/journal.jsonl      append-only event log = commit log
      quarantine/<time>/     what recovery or repair set aside, never deleted

A step is committed when its ``"step"`` record is complete in the journal;
its frame chunks are written (and ``fsync``-ed) before that record
(``_chunks.StepChunks``). Readers
trust only committed records, so after a crash either a whole step is
visible or none of it.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import time
from collections.abc import Iterable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from rig.archive._chunks import StepChunks
from rig.archive._errors import ArchiveError, SessionFinished, os_failure
from rig.archive._index import FRAME_TABLE_DTYPE, SessionIndex
from rig.archive._journal import Journal, read_journal
from rig.archive._layout import (
    FORMAT_VERSION,
    JOURNAL,
    lock_writer,
    read_layout,
    root_attributes,
    write_layout,
)
from rig.archive._material import replace_result
from rig.archive._quarantine import Quarantine
from rig.archive._records import Event, FrameFormat, FrameInfo, FrameRecord, StepRecord, json_safe
from rig.archive._recovery import check_chunks, check_mirror, recover
from rig.archive._store import check_name, group_document, write_atomic
from rig.archive._versions import software_versions

__all__ = ["FORMAT_VERSION", "Archive"]


_RESERVED_KINDS = frozenset(
    {"created", "opened", "closed", "step", "calibration", "material", "repaired"}
)


class Archive:
    """A session archive opened for reading (``mode="r"``) or appending (``"a"``).

    Use ``Archive.create`` or ``Archive.open``; close it (or use ``with``).
    Only one process may append at a time (an advisory lock enforces it); an
    ``Archive`` object is used from one thread at a time.
    """

    def __init__(self, path: Path, *, mode: str, fsync: bool, workers: int | None):
        if mode not in ("r", "a"):
            raise ArchiveError(f"{path}: mode {mode!r}, expected 'r' or 'a'")
        self.path = path
        self.mode = mode
        self._fsync = fsync
        self._lock_fd = -1
        self._journal: Journal | None = None
        self._chunks: StepChunks | None = None
        if mode == "a":
            self._lock_fd = lock_writer(self.path)
        try:
            self._load(workers)
        except BaseException:
            self._release()
            raise

    # -- creating and opening -------------------------------------------------------------

    @classmethod
    def create(
        cls,
        path: str | os.PathLike,
        *,
        plan: Mapping[str, Any],
        rig_config: Mapping[str, Any],
        cameras: Mapping[str, FrameFormat],
        calibration: Mapping[str, Any] | None = None,
        plan_toml: str | None = None,
        zstd_level: int = 1,
        fsync: bool = True,
        workers: int | None = None,
    ) -> Archive:
        """Create a new archive at ``path`` (which must not exist) and open it for appending.

        ``plan``, ``rig_config`` and ``calibration`` are stored as JSON (numpy
        arrays become lists); ``plan_toml`` keeps the plan file's text verbatim.
        ``fsync=False`` keeps the commit order (safe against a killed process)
        but not durability against power loss. ``workers`` threads compress.
        """
        path = Path(path)
        if path.exists():
            raise ArchiveError(f"{path}: already exists; open it with Archive.open(..., mode='a')")
        attributes = root_attributes(
            path,
            plan=plan,
            plan_toml=plan_toml,
            rig_config=rig_config,
            cameras=cameras,
            zstd_level=zstd_level,
        )
        calibration = json_safe(dict(calibration or {}), where="calibration")
        tmp = path.with_name(f".{path.name}.creating")
        shutil.rmtree(tmp, ignore_errors=True)  # left by a crash during an earlier create
        write_layout(tmp, attributes, cameras)
        # The directory appears under its name only when complete.
        os.rename(tmp, path)
        archive = cls(path, mode="a", fsync=fsync, workers=workers)
        if calibration:
            archive.set_calibration(calibration)
        return archive

    @classmethod
    def open(
        cls,
        path: str | os.PathLike,
        *,
        mode: str = "r",
        fsync: bool = True,
        workers: int | None = None,
    ) -> Archive:
        """Open an existing archive, checking its structure.

        With ``mode="a"`` leftovers of a crash (an uncommitted step's chunks, a
        torn journal line, an interrupted material replacement) are moved into
        ``quarantine/<UTC time>/``; ``recovered`` says what was set aside.
        Raises ArchiveDamaged (an ArchiveError) naming what is damaged and where.
        """
        path = Path(path)
        if not path.is_dir():
            raise ArchiveError(f"{path}: no archive here (not a directory)")
        return cls(path, mode=mode, fsync=fsync, workers=workers)

    def _load(self, workers: int | None) -> None:
        layout = read_layout(self.path)
        self._attributes = layout.attributes
        self.cameras = layout.cameras
        self._arrays = layout.arrays
        self._chunks = StepChunks(self.path, layout, fsync=self._fsync, workers=workers)
        contents = read_journal(self.path / JOURNAL)
        self._index = SessionIndex(self.path, self.cameras, contents.events)
        leftovers, strays = check_chunks(
            self.path, self._arrays, self._index, journal_events=len(contents.events)
        )
        check_mirror(self.path, self._index)
        self._events = list(contents.events)
        #: What recovery set aside on this (writable) opening; also in the ``opened`` event.
        self.recovered: dict[str, Any] = {}
        if self.mode == "a":
            quarantine = Quarantine(self.path, fsync=self._fsync)
            try:
                self.recovered = recover(
                    self.path, self._arrays, leftovers, strays, contents, quarantine
                )
                self._journal = Journal(self.path / JOURNAL, contents, fsync=self._fsync)
                self._mirror_calibration()
            except OSError as err:
                where = Path(err.filename) if err.filename else self.path
                raise os_failure(err, where, doing="what recovery sets aside") from err
            kind = "created" if not self._events else "opened"
            self._append_event(kind, {"software": software_versions(), "recovered": self.recovered})

    # -- appending ------------------------------------------------------------------------

    def append_step(
        self,
        step: StepRecord,
        frames: Mapping[str, Sequence[FrameRecord | np.ndarray]],
    ) -> StepRecord:
        """Store a step's frames and commit it atomically; returns the committed record.

        ``frames`` maps each of ``step.cameras`` to its frames. A bare array is
        frame ``sub = i`` (its position in the sequence), exposed for
        ``step.exposures_s[i]`` (or the single exposure), at the time of the call.
        Raises StepAlreadyCommitted if ``step.index`` is already committed.
        """
        self._check_writable()
        now = time.time()
        records = {}
        for camera, sequence in frames.items():
            records[camera] = [_as_record(f, i, step, now) for i, f in enumerate(sequence)]
        self._index.check_new_step(step, records)
        rows = self._chunks.write(step, records, self._index.next_position)
        committed = StepRecord.from_json({**step.to_json(), "committed_at": time.time()})
        event = self._append_event("step", {"step": committed.to_json(), "frames": rows})
        self._index.add_step(event)
        return committed

    def log_event(self, kind: str, **payload: Any) -> Event:
        """Append an event to the log; payload values must be JSON-able (numpy allowed)."""
        self._check_writable()
        if not isinstance(kind, str) or not kind or kind in _RESERVED_KINDS:
            raise ArchiveError(
                f"{self.path}: event kind {kind!r}: use a non-empty str other than the "
                f"archive's own kinds {sorted(_RESERVED_KINDS)}"
            )
        return self._append_event(kind, json_safe(payload, where=f"event {kind!r}"))

    def _append_event(self, kind: str, payload: dict[str, Any]) -> Event:
        assert self._journal is not None
        event = self._journal.append(kind, payload, time=time.time())
        self._events.append(event)
        return event

    def set_calibration(self, calibration: Mapping[str, Any]) -> int:
        """Replace the calibration; returns its new version (1, 2, …). Old ones stay in the log."""
        self._check_writable()
        data = json_safe(dict(calibration), where="calibration")
        version = self.calibration_version + 1
        event = self._append_event("calibration", {"version": version, "calibration": data})
        self._index.add_calibration(event)
        self._mirror_calibration()
        return version

    def _mirror_calibration(self) -> None:
        # The journal is authoritative; calibration/zarr.json mirrors it for zarr readers.
        document = group_document(
            {"version": self.calibration_version, "calibration": self.calibration}
        )
        path = self.path / "calibration" / "zarr.json"
        if path.read_bytes() != document:
            write_atomic(path, document, fsync=self._fsync)

    @contextlib.contextmanager
    def replace_material(self, name: str) -> Iterator[Any]:
        """Write result ``name`` of ``material/`` anew and swap it in atomically.

        Yields an empty ``zarr.Group`` to write into; when the block ends
        without an exception it replaces ``material/<name>`` as a whole.
        """
        import zarr

        self._check_writable()
        check_name(name, what="material result name")
        with replace_result(self.path / "material", name, fsync=self._fsync) as tmp:
            yield zarr.open_group(tmp, mode="w", zarr_format=3)
        self._append_event("material", {"name": name})

    def _check_writable(self) -> None:
        if self._journal is None:
            raise ArchiveError(
                f"{self.path}: not open for appending (opened with mode={self.mode!r} or "
                "closed); use Archive.open(path, mode='a')"
            )

    def close(self) -> None:
        """Record the clean close, trim array shapes to the committed frames, release all."""
        try:
            if self._journal is not None:
                self._chunks.trim(self._index.next_position)
                self._append_event("closed", {"committed_steps": len(self._index.steps)})
        finally:
            self._release()

    def _release(self) -> None:
        """Close the journal, stop the pool and drop the lock, writing nothing."""
        if self._journal is not None:
            self._journal.close()
            self._journal = None
        if self._chunks is not None:
            self._chunks.close()
        if self._lock_fd >= 0:
            os.close(self._lock_fd)
            self._lock_fd = -1

    def __enter__(self) -> Archive:
        return self

    def __exit__(self, *exc_info) -> None:
        self.close()

    # -- reading --------------------------------------------------------------------------

    @property
    def plan(self) -> dict[str, Any]:
        """The measurement plan, as stored."""
        return self._attributes["plan"]

    @property
    def plan_toml(self) -> str | None:
        """The plan file's text, if it was given."""
        return self._attributes["plan_toml"]

    @property
    def rig_config(self) -> dict[str, Any]:
        """The rig configuration, as stored."""
        return self._attributes["rig_config"]

    @property
    def software(self) -> dict[str, str]:
        """Software versions at creation (later openings are in ``events("opened")``)."""
        return self._attributes["software"]

    @property
    def calibration(self) -> dict[str, Any]:
        """The current calibration (``{}`` when none was set)."""
        return self._index.calibration

    @property
    def calibration_version(self) -> int:
        """Version of the current calibration: 0 for none, then 1, 2, …"""
        return self._index.calibration_version

    @property
    def material(self) -> Any:
        """The ``material/`` zarr group (writable in mode ``"a"``)."""
        import zarr

        return zarr.open_group(self.path / "material", mode="r" if self.mode == "r" else "r+")

    def committed_steps(self) -> tuple[int, ...]:
        """Indices of the committed steps, ascending."""
        return tuple(sorted(self._index.steps))

    def step_table(self) -> list[StepRecord]:
        """Every committed step, ordered by index."""
        return [self._index.steps[i] for i in sorted(self._index.steps)]

    def frame_table(self) -> np.ndarray:
        """Every committed frame, in commit order, as a structured array.

        Fields: ``step`` int64, ``camera`` str, ``sub`` int64, ``exposure_s``
        float64, ``timestamp`` float64 (Unix s), ``position`` int64 (row in
        ``frames/<camera>``).
        """
        infos = self._index.frame_infos()
        rows = [(f.step, f.camera, f.sub, f.exposure_s, f.timestamp, f.position) for f in infos]
        return np.array(rows, dtype=FRAME_TABLE_DTYPE)

    def read_frame(self, step: int, camera: str, sub: int = 0) -> np.ndarray:
        """Frame ``sub`` of ``camera`` at committed ``step``: ``(H, W, C)``, camera dtype."""
        info, nbytes = self._index.lookup(step, camera, sub)
        where = f"{self.path}: step {step}, camera {camera!r}, sub {sub}"
        return self._arrays[camera].read(info.position, nbytes=nbytes, where=where)

    def iter_frames(
        self, *, steps: Iterable[int] | None = None, cameras: Iterable[str] | None = None
    ) -> Iterator[tuple[FrameInfo, np.ndarray]]:
        """Yield ``(FrameInfo, image)`` of committed frames, by step, camera and sub."""
        wanted_steps = None if steps is None else set(steps)
        wanted_cameras = None if cameras is None else set(cameras)
        for info in self._index.frame_infos():
            if wanted_steps is not None and info.step not in wanted_steps:
                continue
            if wanted_cameras is not None and info.camera not in wanted_cameras:
                continue
            yield info, self.read_frame(info.step, info.camera, info.sub)

    def events(self, kind: str | None = None) -> list[Event]:
        """The event log (as of opening, plus this handle's appends), optionally one kind."""
        return [e for e in self._events if kind is None or e.kind == kind]

    def check_resumable(self) -> None:
        """Raise ``SessionFinished`` if the recorded session finished: nothing to resume."""
        if any(e.payload.get("action") == "finished" for e in self.events("session")):
            raise SessionFinished(
                f"{self.path}: its session finished ({len(self.committed_steps())} step(s) "
                "committed); nothing to resume. Process it with `rig process`, or submit the "
                "plan again to a new archive"
            )


def _as_record(frame, i: int, step: StepRecord, now: float) -> FrameRecord:
    if isinstance(frame, FrameRecord):
        return frame
    exposures = step.exposures_s
    if len(exposures) == 1:
        exposure = exposures[0]
    elif i < len(exposures):
        exposure = exposures[i]
    else:
        raise ArchiveError(
            f"step {step.index}: bare frame {i} has no exposure: exposures_s has "
            f"{len(exposures)} values; pass FrameRecord(image, sub, exposure_s, timestamp)"
        )
    return FrameRecord(frame, sub=i, exposure_s=exposure, timestamp=now)
