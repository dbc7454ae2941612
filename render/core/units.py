"""Texture units handed out by sampler name.

A renderer's programs read their textures through named samplers
(``btf_images``, ``shadow_maps``, ``peel_now`` …). Each name gets a texture
unit of its own the first time it is asked for and keeps it, so the textures a
renderer binds once (the material's) and those it binds per frame (the shadow
atlas, the peel buffers, a subclass's tables) never land on one another, and
no call site counts units. A name means one sampler in every program of the
renderer that declares it: the MDF's textures are read by the surface program
and the silhouette peel alike.
"""

from __future__ import annotations

import moderngl

from render._errors import RenderError

__all__ = ["TextureUnits"]


class TextureUnits:
    """The texture units of one renderer's programs.

    Parameters
    ----------
    ctx : moderngl.Context
        Its ``GL_MAX_COMBINED_TEXTURE_IMAGE_UNITS`` bounds how many names fit.
    """

    def __init__(self, ctx: moderngl.Context) -> None:
        self._limit = int(ctx.info["GL_MAX_COMBINED_TEXTURE_IMAGE_UNITS"])
        self._units: dict[str, int] = {}
        self._held: dict[str, object] = {}

    def unit(self, name: str) -> int:
        """The unit of sampler ``name``: the next free one the first time it is asked for."""
        if name not in self._units:
            if len(self._units) >= self._limit:
                raise RenderError(
                    f"sampler {name!r}: all {self._limit} texture units of this GL are taken "
                    f"by {list(self._units)}"
                )
            self._units[name] = len(self._units)
        return self._units[name]

    def hold(self, name: str, texture) -> None:
        """Keep ``texture`` on ``name``'s unit for the renderer's life: it is bound again
        by every :meth:`bind_held` (the frame's other bindings may change the GL's)."""
        self.unit(name)
        self._held[name] = texture

    def bind_held(self) -> None:
        """Bind every held texture on its unit."""
        for name, texture in self._held.items():
            texture.use(location=self._units[name])

    def point(self, program: moderngl.Program) -> None:
        """Point each sampler of ``program`` that has a unit here at it."""
        for name, unit in self._units.items():
            if name in program:
                program[name].value = unit

    def use(self, name: str, texture, *programs: moderngl.Program) -> None:
        """Bind ``texture`` on ``name``'s unit now, and point the sampler ``name`` of each
        of ``programs`` that declares one at it."""
        unit = self.unit(name)
        for program in programs:
            if name in program:
                program[name].value = unit
        texture.use(location=unit)
