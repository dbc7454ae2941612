"""The quarantine: where recovery and repair set aside what they do not trust.

Nothing an archive holds is deleted by recovery or repair. Chunk files of an
uncommitted step, a torn journal tail, the leftovers of an interrupted
material replacement, or a journal that repair rewrites are *moved* (or, for
bytes cut off a file, copied) into ``quarantine/<UTC time>/``, keeping their
paths relative to the archive root, so a person can inspect or restore them::

    session.zarr/quarantine/zarr.json                     an empty array node
    session.zarr/quarantine/20261124T044512.123456Z/frames/cam0/c.17.0.0.0
    session.zarr/quarantine/20261124T044512.123456Z/log/journal.jsonl.torn

``quarantine/`` is an empty zarr array node like ``log/``, so zarr readers
list no stray files. The folder of one recovery is created on its first use.
"""

from __future__ import annotations

import datetime
import logging
import os
from pathlib import Path

from rig.archive._store import fsync_dir, hidden_node_document, write_atomic

__all__ = ["QUARANTINE", "Quarantine"]

log = logging.getLogger(__name__)

#: Folder of the quarantine, relative to the archive root.
QUARANTINE = "quarantine"
_DESCRIPTION = (
    "no data: what recovery or repair set aside instead of deleting, one folder per "
    "occasion named by its UTC time (see btfrig docs/archive.md)"
)


class Quarantine:
    """One occasion's quarantine folder in the archive at ``root``; made on first use."""

    def __init__(self, root: Path, *, fsync: bool):
        self.root = root
        self._fsync = fsync
        stamp = datetime.datetime.now(datetime.UTC).strftime("%Y%m%dT%H%M%S.%fZ")
        self.folder = root / QUARANTINE / stamp
        self.moved: list[str] = []

    @property
    def relative_folder(self) -> str:
        """The folder, relative to the archive root (as reported)."""
        return self.folder.relative_to(self.root).as_posix()

    def _target(self, relative: str) -> Path:
        if not self.folder.exists():
            node = self.root / QUARANTINE
            node.mkdir(exist_ok=True)
            if not (node / "zarr.json").exists():
                write_atomic(node / "zarr.json", hidden_node_document(_DESCRIPTION), fsync=False)
            self.folder.mkdir()
        target = self.folder / relative
        target.parent.mkdir(parents=True, exist_ok=True)
        return target

    def move(self, path: Path) -> None:
        """Move file or folder ``path`` (inside the archive) into the quarantine."""
        relative = path.relative_to(self.root).as_posix()
        target = self._target(relative)
        os.rename(path, target)
        if self._fsync:
            fsync_dir(path.parent)
            fsync_dir(target.parent)
        self.moved.append(relative)
        log.info("%s: moved %s to %s", self.root, relative, self.relative_folder)

    def keep_bytes(self, relative: str, data: bytes) -> None:
        """Store ``data`` (bytes about to be cut off or replaced) as ``relative``."""
        target = self._target(relative)
        write_atomic(target, data, fsync=self._fsync)
        self.moved.append(relative)
        log.info("%s: kept %d bytes as %s/%s", self.root, len(data), self.relative_folder, relative)
