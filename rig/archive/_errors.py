"""Errors of the session archive."""

from __future__ import annotations

import errno
import shutil
from pathlib import Path

from rig.errors import RigError

__all__ = [
    "ArchiveDamaged",
    "ArchiveError",
    "ArchiveFull",
    "SessionFinished",
    "StepAlreadyCommitted",
    "os_failure",
]


class ArchiveError(RigError):
    """The archive is damaged, missing, or was asked for something it cannot do.

    The message names the path and, where it applies, the step, camera and
    sub-index concerned, and what would be valid.
    """


class ArchiveDamaged(ArchiveError):
    """What the archive holds contradicts itself: a file, attribute or journal is bad.

    The message names the file or attribute, the bad value and what was
    expected; ``rig repair ARCHIVE`` rebuilds what can be rebuilt.
    """


class ArchiveFull(ArchiveError):
    """The filesystem holding the archive ran out of space during a write.

    Nothing committed is lost: the write was rolled back. ``path`` is the file
    that could not be written, ``needed_bytes`` what the write needed (None
    when unknown) and ``free_bytes`` what the filesystem had free afterwards.
    """

    def __init__(
        self,
        path: Path,
        *,
        doing: str,
        needed_bytes: int | None,
        free_bytes: int,
        then: str = "resume",
    ):
        self.path = path
        self.needed_bytes = needed_bytes
        self.free_bytes = free_bytes
        needs = "" if needed_bytes is None else f"it needs about {_mb(needed_bytes)} MB, "
        super().__init__(
            f"{path}: disk full while writing {doing}: {needs}the filesystem has "
            f"{_mb(free_bytes)} MB free; free space, then {then} (nothing committed was lost)"
        )


class SessionFinished(ArchiveError):
    """The archive's session finished: there is nothing to resume in it."""


class StepAlreadyCommitted(ArchiveError):
    """A step index that is already committed was appended again.

    Raised so that nothing is captured twice after a resume; ``index`` is the
    offending step index and ``next_index`` the one to continue with.
    """

    def __init__(self, message: str, *, index: int, next_index: int):
        super().__init__(message)
        self.index = index
        self.next_index = next_index


def _mb(nbytes: int) -> str:
    return f"{nbytes / 1e6:.3g}"


def os_failure(
    err: OSError,
    path: Path,
    *,
    doing: str,
    needed_bytes: int | None = None,
    then: str = "resume",
) -> ArchiveError:
    """The archive error for a failed write: ArchiveFull when the disk (or quota) is full;
    ``then`` says what to do once space is free."""
    if err.errno in (errno.ENOSPC, errno.EDQUOT):
        try:
            free = shutil.disk_usage(path.parent).free
        except OSError:
            free = 0
        return ArchiveFull(path, doing=doing, needed_bytes=needed_bytes, free_bytes=free, then=then)
    return ArchiveError(f"{path}: writing {doing} failed: {err.strerror or err}")
