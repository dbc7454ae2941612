"""The error of reading and writing other tools' formats."""

from __future__ import annotations

from rig.errors import ConfigError, RigError

__all__ = ["InterchangeError", "InterchangeWriteError"]


class InterchangeError(ConfigError):
    """A file or folder cannot be read or written in an interchange format; the
    message names the file and says what would be valid."""


class InterchangeWriteError(RigError):
    """A file could not be written (a full disk, a folder that is not writable): a
    failure of the machine, not of the input; the message names the file."""
