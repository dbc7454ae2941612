"""`rig view --env`: the environment map a material is lit by, checked before anything is drawn.

``--env`` takes a latitude–longitude ``.hdr`` or ``.exr`` file or the name of
a built-in test environment (``sky``, ``window``, ``studio``); a file that
cannot be read or is not latitude–longitude raises ``typer.BadParameter``
naming it (exit 2).
"""

from __future__ import annotations

import typer

__all__ = ["ENV_FORMS", "parse_environment"]

ENV_FORMS = (
    "a latitude–longitude .hdr or .exr file (width twice the height, +z up), or a built-in "
    "test environment: sky (with a sun), window, studio"
)


def parse_environment(spec: str, rotate_deg: float):
    """The :class:`render.EnvironmentMap` ``spec`` names, turned by ``rotate_deg`` about +z."""
    from render import RenderError, read_environment, synthetic_environment
    from render.environment import SYNTHETIC_ENVIRONMENTS

    try:
        if spec in SYNTHETIC_ENVIRONMENTS:
            return synthetic_environment(spec, height=64).with_view(rotation_deg=rotate_deg)
        return read_environment(spec, rotation_deg=rotate_deg)
    except RenderError as err:
        raise typer.BadParameter(f"{err}; valid: {ENV_FORMS}", param_hint="--env") from err
