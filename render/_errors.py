"""The renderer's domain error."""

from rig.errors import RigError


class RenderError(RigError, ValueError):
    """Bad input to the renderer (a camera, a light, a material it cannot draw) or a
    GL failure; the message names the argument or the GL step and what would be valid.
    """
