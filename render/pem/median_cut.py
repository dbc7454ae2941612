"""An environment as a few directional lights: median cut (seed 002 §3.1, Debevec).

The latitude–longitude map is cut into ``count`` regions of equal light:
``log2(count)`` times, every region is split across its longer side (its width
measured at its middle latitude) where half its energy (luminance × solid
angle) lies on each side. Each region becomes a directional light at its
energy-weighted mean direction carrying the region's whole irradiance
Σ L Δω (RGB). Bright areas get many small regions, dark ones few large ones.

The point-light renderer draws them with its shadow maps (soft edges from
percentage-closer filtering), :data:`render.lights.MAX_LIGHTS` per pass, so
this works for every material the renderer draws (per-view PCA, global SVD,
photometric stereo). :mod:`render.pem` treats the regions as extended lights
whose radiance is filtered to the surface's glossiness.
"""

from __future__ import annotations

import numpy as np

from render._errors import RenderError
from render.lights import MAX_LIGHTS, DirectionalLight

__all__ = ["environment_lights", "median_cut", "median_cut_regions", "render_median_cut"]

_LUMINANCE = np.array([0.2126, 0.7152, 0.0722])  # Rec. 709


def median_cut_regions(environment, count: int) -> list[tuple[int, int, int, int]]:
    """The regions (row0, row1, col0, col1) of the map's pixels, at most ``count``
    (a power of 2): a region of one pixel is not split further."""
    if not (isinstance(count, int) and count >= 1 and count & (count - 1) == 0):
        raise RenderError(f"median cut count = {count!r}: need a power of 2 (1, 2, 4, … )")
    _, solid = environment.pixel_directions()
    power = environment.radiance.astype(np.float64) * solid[..., None]  # (H, W, 3)
    energy = power @ _LUMINANCE
    h, w = energy.shape
    latitude_cos = np.cos(np.radians((np.arange(h) + 0.5) * 180.0 / h - 90.0))
    regions = [(0, h, 0, w)]
    for _ in range(int(np.log2(count))):
        split = []
        for r0, r1, c0, c1 in regions:
            across = (c1 - c0) * latitude_cos[(r0 + r1) // 2] > (r1 - r0)
            if (c1 - c0 if across else r1 - r0) < 2:
                across = not across
            if (c1 - c0 if across else r1 - r0) < 2:
                split.append((r0, r1, c0, c1))
                continue
            profile = energy[r0:r1, c0:c1].sum(axis=0 if across else 1)
            cumulative = np.cumsum(profile)
            cut = int(np.searchsorted(cumulative, cumulative[-1] / 2)) + 1
            cut = min(max(cut, 1), len(profile) - 1)
            if across:
                split += [(r0, r1, c0, c0 + cut), (r0, r1, c0 + cut, c1)]
            else:
                split += [(r0, r0 + cut, c0, c1), (r0 + cut, r1, c0, c1)]
        regions = split
    return regions


def median_cut(environment, count: int) -> tuple[np.ndarray, np.ndarray]:
    """Directions (K, 3) float64 unit and irradiance (K, 3) float64 of the regions.

    K ≤ ``count`` (a power of 2): a region of one pixel is not split further,
    and regions without light are left out. Rotation applies, exposure not.
    """
    vectors, solid = environment.pixel_directions()
    power = environment.radiance.astype(np.float64) * solid[..., None]  # (H, W, 3)
    energy = power @ _LUMINANCE
    directions, irradiance = [], []
    for r0, r1, c0, c1 in median_cut_regions(environment, count):
        part = power[r0:r1, c0:c1].reshape(-1, 3)
        if not part.any():
            continue
        weight = energy[r0:r1, c0:c1].reshape(-1)
        if not weight.any():
            weight = part.sum(axis=1)
        mean = weight @ vectors[r0:r1, c0:c1].reshape(-1, 3)
        norm = np.linalg.norm(mean)
        centre = vectors[(r0 + r1) // 2, (c0 + c1) // 2]
        directions.append(mean / norm if norm > 1e-12 else centre)
        irradiance.append(part.sum(axis=0))
    if not directions:
        return np.zeros((0, 3)), np.zeros((0, 3))
    return np.array(directions), np.array(irradiance)


def environment_lights(environment, count: int) -> list[DirectionalLight]:
    """The median-cut regions as directional lights, the exposure f included."""
    directions, irradiance = median_cut(environment, count)
    lights = []
    for direction, rgb in zip(directions, irradiance * environment.exposure, strict=True):
        peak = float(rgb.max())
        lights.append(DirectionalLight(tuple(direction), tuple(rgb / peak), peak))
    return lights


def render_median_cut(renderer, camera, environment, *, count: int = 16, lights=()) -> np.ndarray:
    """(H, W, 3) float32: ``renderer`` (a :class:`render.Renderer`) under the median-cut
    lights of ``environment`` and any further ``lights``, :data:`MAX_LIGHTS` lights per
    pass, the passes summed."""
    lights = [*lights, *environment_lights(environment, count)]
    image = renderer.render(camera, lights[:MAX_LIGHTS])
    for first in range(MAX_LIGHTS, len(lights), MAX_LIGHTS):
        image += renderer.render(camera, lights[first : first + MAX_LIGHTS])
    return image
