"""The material format's error."""

from __future__ import annotations

from rig.errors import RigError

__all__ = ["MaterialError"]


class MaterialError(RigError, ValueError):
    """A material (an archive's ``material/`` group or a standalone store) is malformed,
    of an unknown version, or was asked to hold something it cannot.

    The message names the path or group, the array or attribute concerned, and
    what would be valid. A subclass of :class:`rig.errors.RigError`, not of the
    archive's error: a material also lives outside any archive (a standalone
    store, a flat-field file), and its problems are about the format, not
    about a session's integrity. A ``ValueError`` too, like the other
    malformed-input errors, so bad arrays given to a writer read as such.
    """
