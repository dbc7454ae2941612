"""Errors of the session archive."""

from __future__ import annotations

from rig.errors import RigError

__all__ = ["ArchiveError", "StepAlreadyCommitted"]


class ArchiveError(RigError):
    """The archive is damaged, missing, or was asked for something it cannot do.

    The message names the path and, where it applies, the step, camera and
    sub-index concerned, and what would be valid.
    """


class StepAlreadyCommitted(ArchiveError):
    """A step index that is already committed was appended again.

    Raised so that nothing is captured twice after a resume; ``index`` is the
    offending step index and ``next_index`` the one to continue with.
    """

    def __init__(self, message: str, *, index: int, next_index: int):
        super().__init__(message)
        self.index = index
        self.next_index = next_index
