"""Partial environment maps: median-cut regions as extended, glossiness-filtered lights (seed 002).

Every median-cut region (:func:`render.pem.median_cut.median_cut_regions`) is its own
partial environment map: the map's light Σ L Δω inside the region and nothing
outside. Its MIP pyramid sums 2×2 texels of light (and their light-weighted mean
direction), so level 0 is the region's pixels and the top level the region's
single light — what :mod:`render.pem.median_cut` draws. A surface's lobe reads the
level whose texel spans the lobe's half-width at half maximum (seed 002 §3.2:
a sharp lobe reads fine levels, a broad one coarse levels):

* Lambert, cos θ: half-width 60°, so a region is a handful of texels or one;
* Blinn–Phong (n·h)^s: around the mirror direction the lobe falls as
  cos^s(θ/2), half-width 2·arccos(2^(−1/s)), so a sharp lobe sees the
  region's bright spots one by one instead of one averaged light.

The region's light for that surface is the lobe-weighted sum over its texels at
that level — the simplest faithful form of seed 002's filtered lookup: the colour
and strength of a region depend on the glossiness, and the sum over regions
weights each by its own visibility (eq. (5)). :func:`partial_maps` makes the
table of texels the GL renderer (:mod:`render.pem.renderer`) reads and
:func:`pem_radiance` sums on the CPU. A region's soft shadow edge comes from
its angular radius: √2 × the light-weighted RMS angle of its pixels from its
direction, the radius of a uniform disc of that spread.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from render._errors import RenderError
from render.pem.median_cut import median_cut_regions

__all__ = [
    "MAX_LOBE_TEXELS",
    "PartialMaps",
    "blinn_half_width",
    "lobe_level",
    "partial_maps",
    "pem_radiance",
    "region_pyramid",
    "region_radiance",
]

#: Half-width at half maximum of the cosine (Lambert) lobe.
_LAMBERT_HALF_WIDTH = np.pi / 3
#: Texels one lobe reads over all regions at most: a sharper lobe on a larger map
#: reads a coarser level (each fragment sums them, so they bound a frame's cost).
MAX_LOBE_TEXELS = 1024


def blinn_half_width(shininess: float) -> float:
    """Half-width (rad) at half maximum of (n·h)^s about the mirror direction."""
    return 2.0 * float(np.arccos(2.0 ** (-1.0 / shininess)))


def lobe_level(half_width: float, height: int) -> int:
    """The coarsest pyramid level whose texel (π/height · 2^level) is no wider than
    ``half_width`` radians; 0 when even a pixel is wider."""
    texel = np.pi / height
    return max(int(np.floor(np.log2(max(half_width / texel, 1.0)))), 0)


def _pyramid(vectors, power, region, level: int) -> tuple[np.ndarray, np.ndarray]:
    r0, r1, c0, c1 = region
    power = power[r0:r1, c0:c1]
    weight = power.sum(axis=2)
    step = 2**level
    rows, cols = -(-(r1 - r0) // step) * step, -(-(c1 - c0) // step) * step
    pad = ((0, rows - (r1 - r0)), (0, cols - (c1 - c0)), (0, 0))
    blocks = (rows // step, step, cols // step, step)
    light = np.pad(power, pad).reshape(*blocks, 3).sum(axis=(1, 3))
    moment = np.pad(vectors[r0:r1, c0:c1] * weight[..., None], pad)
    mean = moment.reshape(*blocks, 3).sum(axis=(1, 3))
    lit = light.sum(axis=2) > 0
    mean, light = mean[lit], light[lit]
    norm = np.linalg.norm(mean, axis=1, keepdims=True)
    return mean / np.maximum(norm, 1e-300), light


def _power(environment) -> tuple[np.ndarray, np.ndarray]:
    vectors, solid = environment.pixel_directions()
    return vectors, environment.radiance.astype(np.float64) * solid[..., None]


def region_pyramid(environment, region, level: int) -> tuple[np.ndarray, np.ndarray]:
    """Directions (M, 3) unit and light Σ L Δω (M, 3) of a region's texels at ``level``:
    blocks of 2^level × 2^level pixels, each at its light-weighted mean direction.
    Blocks without light are left out. Rotation applies, exposure not."""
    return _pyramid(*_power(environment), region, level)


@dataclass(frozen=True)
class PartialMaps:
    """The lit median-cut regions of an environment and their texels at two levels.

    Attributes
    ----------
    directions : (K, 3) float64, unit
        Each region's light-weighted mean direction (its top level: the shadow
        map's direction).
    light : (K, 3) float64
        Each region's light Σ L Δω, exposure included.
    angular_radius : (K,) float64, radians
        √2 × the light-weighted RMS angle of the region's pixels from its direction.
    diffuse, glossy : (K, 2) int64
        First and count of each region's texels at the Lambert level and at the
        lobe's level in ``texel_directions`` / ``texel_light`` (count 0: none).
    texel_directions : (M, 3) float64, unit
    texel_light : (M, 3) float64
        Light Σ L Δω of each texel, exposure included.
    levels : (int, int)
        The Lambert and the lobe level asked for (a region smaller than a level's
        texel is read at its own top).
    """

    directions: np.ndarray
    light: np.ndarray
    angular_radius: np.ndarray
    diffuse: np.ndarray
    glossy: np.ndarray
    texel_directions: np.ndarray
    texel_light: np.ndarray
    levels: tuple[int, int]


def partial_maps(environment, count: int, *, shininess: float | None = None,
                 mip: bool = True) -> PartialMaps:  # fmt: skip
    """The partial maps of ``environment``'s ``count`` median-cut regions.

    ``shininess`` (the Blinn–Phong exponent s > 0) adds the lobe's texels; ``None``:
    Lambert only. ``mip=False`` reads every region at its top level: the
    directional lights of :mod:`render.pem.median_cut`. The lobe's level is raised
    until its texels over all regions are at most :data:`MAX_LOBE_TEXELS`.
    """
    if shininess is not None and not (np.isfinite(shininess) and shininess > 0):
        raise RenderError(f"shininess = {shininess}: need a finite exponent > 0")
    vectors, power = _power(environment)
    h = environment.height
    regions = [r for r in median_cut_regions(environment, count)
               if power[r[0]:r[1], r[2]:r[3]].any()]  # fmt: skip
    tops = [int(np.ceil(np.log2(max(r1 - r0, c1 - c0, 1)))) for r0, r1, c0, c1 in regions]
    top = max(tops, default=0)
    diffuse_level = lobe_level(_LAMBERT_HALF_WIDTH, h) if mip else top
    levels = [(min(diffuse_level, t),) for t in tops]
    glossy_level = -1
    if shininess is not None:
        glossy_level = lobe_level(blinn_half_width(shininess), h) if mip else top
        while glossy_level < top and _texel_count(regions, tops, glossy_level) > MAX_LOBE_TEXELS:
            glossy_level += 1
        levels = [(*lv, min(glossy_level, t)) for lv, t in zip(levels, tops, strict=True)]
    directions, light, radius = [], [], []
    ranges = np.zeros((len(regions), 2, 2), np.int64)
    texel_d, texel_l, first = [], [], 0
    weight = power.sum(axis=2)
    for k, (region, region_levels) in enumerate(zip(regions, levels, strict=True)):
        d, e = _pyramid(vectors, power, region, tops[k])
        directions.append(d[0])
        light.append(e[0])
        r0, r1, c0, c1 = region
        w = weight[r0:r1, c0:c1]
        cosine = np.clip(vectors[r0:r1, c0:c1] @ d[0], -1.0, 1.0)
        radius.append(np.sqrt(2.0 * (w * np.arccos(cosine) ** 2).sum() / w.sum()))
        for j, level in enumerate(region_levels):
            d, e = _pyramid(vectors, power, region, level)
            ranges[k, j] = first, len(d)
            texel_d.append(d)
            texel_l.append(e)
            first += len(d)
    f = environment.exposure
    return PartialMaps(
        directions=np.array(directions).reshape(-1, 3),
        light=np.array(light).reshape(-1, 3) * f,
        angular_radius=np.array(radius, np.float64),
        diffuse=ranges[:, 0],
        glossy=ranges[:, 1],
        texel_directions=np.concatenate(texel_d or [np.zeros((0, 3))]),
        texel_light=np.concatenate(texel_l or [np.zeros((0, 3))]) * f,
        levels=(diffuse_level, glossy_level),
    )


def _texel_count(regions, tops, level: int) -> int:
    """Texels of the regions at ``level`` (each at most at its top), dark ones included."""
    count = 0
    for (r0, r1, c0, c1), top in zip(regions, tops, strict=True):
        step = 2 ** min(level, top)
        count += -(-(r1 - r0) // step) * -(-(c1 - c0) // step)
    return count


def _unit(name: str, vector) -> np.ndarray:
    v = np.asarray(vector, np.float64)
    norm = np.linalg.norm(v, axis=-1, keepdims=True) if v.ndim else np.zeros(1)
    if v.shape[-1:] != (3,) or not np.all(np.isfinite(v)) or not np.all(norm > 0):
        raise RenderError(f"{name} = {vector!r}: expected finite, non-zero (x, y, z) vectors")
    return v / norm


def _lobe_sums(maps: PartialMaps, ranges, normal, view, horizon, shininess) -> np.ndarray:
    """(K, …, 3): per region Σ over its texels in ``ranges`` above ``horizon``'s horizon of
    their light × (n·l)⁺, or × (n·h)^s where n·l > 0 (``shininess`` s; None: the cosine)."""
    totals = np.zeros((len(ranges), *np.broadcast_shapes(normal.shape, view.shape)[:-1], 3))
    for k, (first, count) in enumerate(ranges):
        d = maps.texel_directions[first : first + count]
        cosine = np.clip(normal @ d.T, 0.0, None) * (horizon @ d.T > 0)
        if shininess is None:
            weight = cosine
        else:
            half = d + view[..., None, :]
            half /= np.maximum(np.linalg.norm(half, axis=-1, keepdims=True), 1e-12)
            n_dot_h = np.clip(np.einsum("...k,...mk->...m", normal, half), 0.0, None)
            weight = n_dot_h**shininess * (cosine > 0)
        totals[k] = weight @ maps.texel_light[first : first + count]
    return totals


def region_radiance(maps: PartialMaps, normal, view, *, surface=None, albedo=1.0, specular=0.0,
                    shininess=40.0) -> np.ndarray:  # fmt: skip
    """(K, …, 3): what each region of ``maps`` sends towards ``view`` from surfaces of unit
    shading ``normal`` (…, 3) unoccluded, its texels above the horizon of ``surface`` (the
    geometric normals (…, 3), ``normal`` by default: a sheet is lit from its front only) only:
    ``albedo`` (a number or (…, 3)) × its texels at the
    Lambert level × (n·l)⁺ + ``specular`` × its texels at the lobe's level × (n·h)^s where
    n·l > 0 (``maps`` made with this ``shininess``), exposure included. Times each
    region's visibility and summed, it is a surface's radiance (seed 002 eq. (5))."""
    if not (np.all(np.isfinite(albedo)) and np.all(np.asarray(albedo) >= 0)
            and np.isfinite(specular) and specular >= 0
            and np.isfinite(shininess) and shininess > 0):  # fmt: skip
        raise RenderError(
            f"albedo = {albedo}, specular = {specular}, shininess = {shininess}: need albedo ≥ 0, "
            "specular ≥ 0, shininess > 0, all finite"
        )
    normal, view = _unit("normal", normal), _unit("view", view)
    surface = normal if surface is None else _unit("surface", surface)
    lambert = _lobe_sums(maps, maps.diffuse, normal, view, surface, None)
    total = np.asarray(albedo, np.float64) * lambert
    if specular > 0:
        total = total + specular * _lobe_sums(maps, maps.glossy, normal, view, surface, shininess)
    return total


def pem_radiance(environment, count, normal, view, *, surface=None, albedo=1.0, specular=0.0,
                 shininess=40.0, mip=True) -> np.ndarray:  # fmt: skip
    """(…, 3) radiance of flat, unoccluded surfaces (``normal``, ``view`` (…, 3), normalised;
    ``surface``: see :func:`region_radiance`) under the ``count`` median-cut regions: Σ over
    regions of ``albedo`` (a number or (…, 3)) × the Lambert part read at the Lambert level
    plus ``specular`` × the Blinn–Phong lobe read at its level, exposure included.
    ``mip=False`` reads every region at its top level — the directional lights."""
    maps = partial_maps(environment, count, shininess=shininess if specular > 0 else None, mip=mip)
    shading = {"surface": surface, "albedo": albedo, "specular": specular, "shininess": shininess}
    return region_radiance(maps, normal, view, **shading).sum(axis=0)
