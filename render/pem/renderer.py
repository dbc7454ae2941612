"""The GL renderer under partial environment maps: median-cut regions as extended lights.

Each lit median-cut region of the environment (:func:`render.pem.partial_maps`)
is one light of the point-light :class:`render.Renderer`: its shadow map looks
from the region's direction, and its percentage-closer kernel is widened to
the penumbra an occluder ``occluder_mm`` above the receiver casts under a disc
light of the region's angular radius ρ (10–90 % over 1.38 · occluder_mm · tan ρ),
so a large, dim region casts soft shadows and a sun a sharp one. One height for
every occluder: finding each blocker's own depth (percentage-closer soft shadows)
would need the depth atlas read without comparison. What the region sends depends on the surface:

* photometric-stereo maps: the fragment sums the region's texels at the
  Lambert level × albedo × (n·l)⁺ and at the level of the Blinn–Phong lobe ×
  specular × (n·h)^s, with the bumped normal, times the region's visibility
  (seed 002 eq. (5)) — what :func:`render.pem.pem_radiance` sums on the CPU;
* a BTF: the region's whole light from its direction (its top level), as the
  median-cut lights. The BTF is glossy by itself, but it is known only at the
  measured light directions (15° apart for H1) and blended over the four
  nearest, so detail finer than the Lambert level's 60° would mostly fall
  between measured lights, while each texel would cost the BTF another light
  blend and its weights for every view slot.

Regions and further lamps go :data:`render.lights.MAX_LIGHTS` to a pass (one
shadow map each), the passes summed.
"""

from __future__ import annotations

from typing import ClassVar

import moderngl
import numpy as np

from render._errors import RenderError
from render.lights import MAX_LIGHTS, DirectionalLight
from render.pem.regions import PartialMaps, partial_maps
from render.points.renderer import Renderer

__all__ = ["PemRenderer"]

#: Texel-table entries per texture row (two RGBA texels each: direction, light).
_ROW = 1024
#: Largest angular radius whose tangent sizes a penumbra (beyond it the tangent explodes).
_MAX_RADIUS = 1.4
#: Shadow tap spacing per penumbra radius h·tan ρ: the 5 taps act as a box 5 spacings wide,
#: whose 10–90 % rise (4 spacings) is set to a disc light's, 1.38 h·tan ρ.
_TAP_PER_RADIUS = 1.38 / 4


class PemRenderer(Renderer):
    """A :class:`render.Renderer` that also draws partial environment maps.

    Parameters
    ----------
    material, mesh
        As for :class:`render.Renderer`, and its keyword options (``specular``,
        ``shininess``: the lobe whose level the regions are read at).
    occluder_mm : float, optional
        Height of an occluder above its shadow, scene units, that a region's
        penumbra is sized for (see the module). A tenth of the mesh's size by default.
    mip : bool
        False reads every region at its top level: the directional lights of
        :mod:`render.pem.median_cut` (for comparison).
    """

    _features: ClassVar[dict[str, int]] = {"PEM": 1}

    def __init__(self, material, mesh, *, occluder_mm: float | None = None, mip: bool = True,
                 specular: float = 0.0, shininess: float = 40.0, **options) -> None:  # fmt: skip
        super().__init__(material, mesh, specular=specular, shininess=shininess, **options)
        depth = 0.2 * self.bounds_radius if occluder_mm is None else occluder_mm
        if not (np.isfinite(depth) and depth >= 0):
            raise RenderError(f"occluder_mm = {occluder_mm}: must be a number ≥ 0 (scene units)")
        self.occluder_mm = float(depth)
        self.mip = bool(mip)
        self._shininess = float(shininess) if "ps" in self.layers and specular > 0 else None
        self._cached: tuple | None = None
        self._table: moderngl.Texture | None = None
        self._pass: tuple[np.ndarray, np.ndarray] | None = None

    def maps_for(self, environment, count: int) -> PartialMaps:
        """The regions of ``environment`` read at this renderer's levels (made once per map,
        rotation, exposure and count; its texel table goes to the GPU then)."""
        cached = self._cached
        key = (environment.rotation_deg, environment.exposure, count)
        if cached is None or cached[0] is not environment.radiance or cached[1] != key:
            maps = partial_maps(environment, count, shininess=self._shininess, mip=self.mip)
            self._upload(maps)
            self._cached = (environment.radiance, key, maps)
        return self._cached[2]

    def _upload(self, maps: PartialMaps) -> None:
        entries = max(len(maps.texel_directions), 1)
        rows = -(-entries // _ROW)
        table = np.zeros((rows * _ROW, 2, 4), np.float32)
        table[: len(maps.texel_directions), 0, :3] = maps.texel_directions
        table[: len(maps.texel_light), 1, :3] = maps.texel_light
        if self._table is not None:
            self._table.release()
        self._table = self.ctx.texture((2 * _ROW, rows), 4, table.tobytes(), dtype="f4")
        self._table.filter = (moderngl.NEAREST, moderngl.NEAREST)

    def render_environment(self, camera, environment, *, count: int = 16, lights=()) -> np.ndarray:
        """(H, W, 3) float32: the scene under ``environment``'s ``count`` median-cut regions
        (a power of 2) and any further ``lights``, exposure included."""
        maps = self.maps_for(environment, count)
        lights = list(lights)
        regions = [
            DirectionalLight(tuple(d), tuple(rgb / rgb.max()), float(rgb.max()))
            for d, rgb in zip(maps.directions, maps.light, strict=True)
        ]
        texels = np.zeros((len(lights) + len(regions), 4), np.int32)
        texels[len(lights) :] = np.hstack([maps.diffuse, maps.glossy])
        spread = np.zeros(len(lights) + len(regions), np.float32)
        radius = np.minimum(maps.angular_radius, _MAX_RADIUS)
        spread[len(lights) :] = _TAP_PER_RADIUS * self.occluder_mm * np.tan(radius)
        every = [*lights, *regions]
        image = None
        for first in range(0, max(len(every), 1), MAX_LIGHTS):
            part = slice(first, first + MAX_LIGHTS)
            self._pass = texels[part], spread[part]
            try:
                drawn = self.render(camera, every[part])
            finally:
                self._pass = None
            image = drawn if image is None else image + drawn
        return image

    def _bind_lights(self, program, lights, units) -> None:
        texels, spread = self._pass or (
            np.zeros((len(lights), 4), np.int32),
            np.zeros(len(lights), np.float32),
        )
        if "light_texels" in program:
            program["light_texels"].write(texels.tobytes())
        if "light_spread" in program:
            program["light_spread"].write(spread.tobytes())
        if self._table is not None:
            units.use("pem_texels", self._table, program)

    def release(self) -> None:
        if self._table is not None:
            self._table.release()
            self._table = None
        super().release()
