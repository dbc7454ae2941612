"""The error of reading and writing other tools' formats."""

from __future__ import annotations

from rig.errors import ConfigError

__all__ = ["InterchangeError"]


class InterchangeError(ConfigError):
    """A file or folder cannot be read or written in an interchange format; the
    message names the file and says what would be valid."""
