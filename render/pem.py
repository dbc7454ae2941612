"""Partial environment maps: median-cut regions as extended, glossiness-filtered lights (seed 002).

Every median-cut region (:func:`render.median_cut.median_cut_regions`) is its own
partial environment map: the map's light Σ L Δω inside the region and nothing
outside. Its MIP pyramid sums 2×2 texels of light (and their light-weighted mean
direction), so level 0 is the region's pixels and the top level the region's
single light — what :mod:`render.median_cut` draws. A surface's lobe reads the
level whose texel spans the lobe's half-width at half maximum (seed 002 §3.2:
a sharp lobe reads fine levels, a broad one coarse levels):

* Lambert, cos θ: half-width 60°, so a region is a handful of texels or one;
* Blinn–Phong (n·h)^s: around the mirror direction the lobe falls as
  cos^s(θ/2), half-width 2·arccos(2^(−1/s)), so a sharp lobe sees the
  region's bright spots one by one instead of one averaged light.

The region's light for that surface is the lobe-weighted sum over its texels at
that level — the simplest faithful form of seed 002's filtered lookup: the colour
and strength of a region depend on the glossiness, and the sum over regions
weights each by its own visibility (eq. (5)). Its soft shadow edge comes from
the region's angular extent (:func:`pcf_radius`).
"""

from __future__ import annotations

import numpy as np

from render._errors import RenderError
from render.median_cut import median_cut_regions

__all__ = ["blinn_half_width", "lobe_level", "pcf_radius", "pem_radiance", "region_pyramid"]

#: Half-width at half maximum of the cosine (Lambert) lobe.
_LAMBERT_HALF_WIDTH = np.pi / 3


def blinn_half_width(shininess: float) -> float:
    """Half-width (rad) at half maximum of (n·h)^s about the mirror direction."""
    return 2.0 * float(np.arccos(2.0 ** (-1.0 / shininess)))


def lobe_level(half_width: float, height: int) -> int:
    """The coarsest pyramid level whose texel (π/height · 2^level) is no wider than
    ``half_width`` radians; 0 when even a pixel is wider."""
    texel = np.pi / height
    return max(int(np.floor(np.log2(max(half_width / texel, 1.0)))), 0)


def region_pyramid(environment, region, level: int) -> tuple[np.ndarray, np.ndarray]:
    """Directions (M, 3) unit and light Σ L Δω (M, 3) of a region's texels at ``level``:
    blocks of 2^level × 2^level pixels, each at its light-weighted mean direction.
    Blocks without light are left out. Rotation applies, exposure not."""
    r0, r1, c0, c1 = region
    vectors, solid = environment.pixel_directions()
    power = environment.radiance[r0:r1, c0:c1].astype(np.float64) * solid[r0:r1, :, None]
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


def _unit(name: str, vector) -> np.ndarray:
    v = np.asarray(vector, np.float64)
    if v.shape != (3,) or not np.all(np.isfinite(v)) or not np.linalg.norm(v) > 0:
        raise RenderError(f"{name} = {vector!r}: expected a finite, non-zero (x, y, z)")
    return v / np.linalg.norm(v)


def _shade(directions, light, normal, view, albedo, specular, shininess):
    cosine = np.clip(directions @ normal, 0.0, None)
    half = directions + view
    half /= np.maximum(np.linalg.norm(half, axis=1, keepdims=True), 1e-12)
    lobe = specular * np.clip(half @ normal, 0.0, None) ** shininess * (cosine > 0)
    return (albedo * cosine)[:, None] * light, lobe[:, None] * light


def pem_radiance(
    environment, count, normal, view, *, albedo=1.0, specular=0.0, shininess=40.0, mip=True
) -> np.ndarray:
    """(3,) radiance of a flat, unoccluded surface (``normal``, ``view`` normalised) under
    the ``count`` median-cut regions: Σ over regions of the Lambert part read at the
    Lambert level plus the Blinn–Phong lobe read at its level, exposure included.
    ``mip=False`` reads every region at its top level — the directional lights."""
    if not (np.isfinite(albedo) and albedo >= 0 and np.isfinite(specular) and specular >= 0
            and np.isfinite(shininess) and shininess > 0):  # fmt: skip
        raise RenderError(
            f"albedo = {albedo}, specular = {specular}, shininess = {shininess}: need albedo ≥ 0, "
            "specular ≥ 0, shininess > 0, all finite"
        )
    normal, view = _unit("normal", normal), _unit("view", view)
    h = environment.height
    total = np.zeros(3)
    for region in median_cut_regions(environment, count):
        top = int(np.ceil(np.log2(max(region[1] - region[0], region[3] - region[2], 1))))
        diffuse_level = min(lobe_level(_LAMBERT_HALF_WIDTH, h), top) if mip else top
        glossy_level = min(lobe_level(blinn_half_width(shininess), h), top) if mip else top
        d, e = region_pyramid(environment, region, diffuse_level)
        total += _shade(d, e, normal, view, albedo, specular, shininess)[0].sum(axis=0)
        if specular > 0:
            d, e = region_pyramid(environment, region, glossy_level)
            total += _shade(d, e, normal, view, albedo, specular, shininess)[1].sum(axis=0)
    return total * environment.exposure


def pcf_radius(environment, region, shadow_texel: float, depth: float) -> float:
    """The percentage-closer filter radius (shadow-map texels) of a region: the
    penumbra an occluder ``depth`` scene units above the receiver casts under a
    light of the region's angular radius √(Ω/π), in texels of ``shadow_texel``
    scene units; at least 1 (the renderer's hard-edge kernel)."""
    r0, r1, c0, c1 = region
    _, solid = environment.pixel_directions()
    omega = float(solid[r0:r1, 0].sum()) * (c1 - c0)
    angular_radius = np.sqrt(omega / np.pi)
    return max(depth * np.tan(min(angular_radius, 1.5)) / shadow_texel, 1.0)
