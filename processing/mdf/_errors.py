"""The MDF domain error."""

from rig.errors import RigError


class MdfError(RigError, ValueError):
    """Malformed input to an MDF reconstruction function.

    The message names the argument, the value that was wrong and what would be
    valid. It subclasses ``ValueError`` too, so callers that treat bad
    arguments generically still catch it.
    """
