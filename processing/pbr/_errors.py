"""The PBR fit's error."""

from __future__ import annotations

from rig.errors import RigError

__all__ = ["PbrError"]


class PbrError(RigError, ValueError):
    """Arrays given to the PBR fit do not fit together; the message names the argument,
    the shape found and the shape expected."""
