"""The BTF domain error."""

from rig.errors import RigError


class BtfError(RigError, ValueError):
    """Malformed input to a BTF compression or interpolation function.

    The message names the argument, the value that was wrong and what would be
    valid. Hard but well-formed inputs (a constant view, fewer lights than
    components, duplicated directions) are not errors: they come back with a
    reduced ``rank``.
    """
