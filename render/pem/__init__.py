"""Partial environment maps (seed 002): an environment as median-cut regions, drawn
as extended lights with their own shadow maps by the point-light renderer.

Median cut and the regions as directional lights (:mod:`render.pem.median_cut`);
the regions' MIP pyramids read at the surface's glossiness and their CPU reference
(:mod:`render.pem.regions`); :class:`PemRenderer` (:mod:`render.pem.renderer`).
"""

from render.pem.median_cut import environment_lights, render_median_cut
from render.pem.regions import PartialMaps, partial_maps, pem_radiance
from render.pem.renderer import PemRenderer

__all__ = [
    "PartialMaps",
    "PemRenderer",
    "environment_lights",
    "partial_maps",
    "pem_radiance",
    "render_median_cut",
]
