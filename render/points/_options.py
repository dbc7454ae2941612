"""A point-light renderer's options, checked where they come in: the layers the
material can be drawn with, its tile size and the shading options, each refused
with what would be valid."""

from __future__ import annotations

import numpy as np

from render._errors import RenderError
from render.core.lookup import BLEND_METHODS
from rig.material import Material

__all__ = ["LAYERS", "check_shading", "checked_layers", "checked_tile_mm"]

#: What can shade the surface: the BTF, the photometric-stereo maps, the PBR fit.
LAYERS = ("btf", "ps", "pbr")


def checked_layers(material: Material, layers) -> tuple[str, ...]:
    """The layers to draw: ``layers`` as asked, or by default the measurement the
    material holds (its PBR fit when it holds nothing else)."""
    parts = (("btf", material.btf), ("ps", material.frontal_ps()), ("pbr", material.pbr))
    held = tuple(name for name, part in parts if part is not None)
    # by default the measurement itself; the PBR fit when it is all there is
    measured = tuple(name for name in held if name != "pbr")
    wanted = (measured or held) if layers is None else tuple(layers)
    unknown = [name for name in wanted if name not in LAYERS]
    if unknown:
        raise RenderError(f"layers {unknown}: valid are {LAYERS}")
    if "pbr" in wanted and len(wanted) > 1:
        raise RenderError(
            f"layers {list(wanted)}: the PBR fit stands for the BTF and the PS maps; "
            "render it alone (layers=('pbr',))"
        )
    missing = [name for name in wanted if name not in held]
    if missing or not wanted:
        raise RenderError(
            f"material {str(material.source)!r} holds {list(held) or 'nothing to render'}; "
            f"cannot render layers {missing or list(wanted)}"
        )
    return wanted


def checked_tile_mm(material: Material, tile_mm: float | None) -> float:
    """mm of surface one repeat of the sample covers: ``tile_mm``, or the sample's side."""
    tile = material.sample_mm if tile_mm is None else tile_mm
    if not (np.isfinite(tile) and tile > 0):
        raise RenderError(f"tile_mm = {tile_mm}: must be a positive number of mm")
    return float(tile)


def check_shading(
    *, light_method: str, view_method: str, specular: float, shininess: float, ambient: float
) -> None:
    """RenderError naming the first option out of its range (see ``Renderer``)."""
    for name, method in (("light_method", light_method), ("view_method", view_method)):
        if method not in BLEND_METHODS:
            raise RenderError(f"{name} = {method!r}: valid are {BLEND_METHODS}")
    if not (np.isfinite(specular) and specular >= 0 and np.isfinite(shininess)
            and shininess > 0):  # fmt: skip
        raise RenderError(
            f"specular = {specular}, shininess = {shininess}: need specular ≥ 0, shininess > 0"
        )
    if not (np.isfinite(ambient) and 0 <= ambient <= 1):
        raise RenderError(f"ambient = {ambient}: valid is a fraction 0 … 1 of each light")
