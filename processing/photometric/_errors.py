"""The photometric-stereo domain error."""

from rig.errors import RigError


class PhotometricError(RigError, ValueError):
    """Malformed input to a photometric-stereo function.

    The message names the argument, the value that was wrong and what would be
    valid. It subclasses ``ValueError`` too, so callers that treat bad
    arguments generically still catch it.
    """
