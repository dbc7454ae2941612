"""Material arrays → GL textures: the BTF as float16 texture arrays, the weights
and direction lookups as float32 textures, the photometric-stereo maps.

Texel grids follow ``rig.geometry.texel_centers_mm`` (row 0 at +y); GL's first
row is at texture coordinate t = 0, the sample's −y edge, so rows are flipped
on upload. Textures repeat (the sample tiles the surface) and carry mipmaps.
"""

from __future__ import annotations

from dataclasses import dataclass

import moderngl
import numpy as np

from render._errors import RenderError
from render.core.lookup import DirectionLookup
from rig.geometry import LIGHT_COSINE_FLOOR
from rig.material import GlobalSVD, PbrMaps, pbr_layers, sheen_albedo

__all__ = [
    "BtfTextures",
    "PbrTextures",
    "PsTextures",
    "light_cosine_texture",
    "lookup_texture",
    "material_sampling",
    "upload_btf",
    "upload_pbr",
    "upload_ps",
]


def material_sampling(texture, channels: int):
    """Sample `texture` as the material's maps are: repeating, trilinear over mipmaps, a grey
    channel read as grey RGB."""
    if channels == 1:
        texture.swizzle = "RRR1"
    texture.repeat_x = texture.repeat_y = True
    texture.build_mipmaps()
    texture.filter = (moderngl.LINEAR_MIPMAP_LINEAR, moderngl.LINEAR)
    return texture


def _layers(ctx: moderngl.Context, name: str, stack: np.ndarray) -> moderngl.TextureArray:
    """(layers, N, N, C) float16 → a repeating, mipmapped 2-D texture array."""
    layers, n, _, channels = stack.shape
    limit = int(ctx.info["GL_MAX_ARRAY_TEXTURE_LAYERS"])
    if layers > limit:
        raise RenderError(
            f"material btf {name}: {layers} texture layers, this GL allows {limit}; "
            "compress with fewer components"
        )
    data = np.ascontiguousarray(stack[:, ::-1], dtype=np.float16)
    return material_sampling(
        ctx.texture_array((n, n, layers), channels, data, dtype="f2"), channels
    )


def _rows(ctx: moderngl.Context, name: str, rows: np.ndarray) -> moderngl.Texture:
    """(height, width, 4) float32 → a texture read by texelFetch."""
    height, width = rows.shape[:2]
    limit = int(ctx.info["GL_MAX_TEXTURE_SIZE"])
    if height > limit:
        raise RenderError(f"{name}: {height} rows exceed this GL's texture size {limit}")
    texture = ctx.texture((width, height), 4, np.ascontiguousarray(rows, np.float32), dtype="f4")
    texture.filter = (moderngl.NEAREST, moderngl.NEAREST)
    return texture


def _coefficients(weights: np.ndarray) -> np.ndarray:
    """(rows, c) → (rows, ⌈c/4⌉, 4) float32, zero padded."""
    rows, c = weights.shape
    padded = np.zeros((rows, 4 * ((c + 3) // 4)), np.float32)
    padded[:, :c] = weights
    return padded.reshape(rows, -1, 4)


@dataclass
class BtfTextures:
    """The BTF on the GPU. ``images``: per group (a view slot's basis images then its
    mean, "pca"; a light's eigen images, "svd") their values, ``channels`` per texel each,
    packed four to an RGBA texel into ``packed`` layers, so a fragment reads a slot
    in ⌈channels·(c + 1)/4⌉ fetches, not c + 1."""

    kind: str
    components: int
    n_lights: int
    channels: int
    packed: int
    weights: moderngl.Texture
    images: moderngl.TextureArray

    def release(self) -> None:
        self.weights.release()
        self.images.release()


def _packed(groups: np.ndarray) -> tuple[np.ndarray, int]:
    """(g, m, N, N, C) images → (g·P, N, N, 4) layers, value m·C + channel of group i
    at layer i·P + ⌊value/4⌋, component value % 4 (zero padded); and P."""
    g, m, n, _, channels = groups.shape
    packed = -(-m * channels // 4)
    values = np.zeros((g, n, n, 4 * packed), np.float16)
    values[..., : m * channels] = np.moveaxis(groups, 1, 3).reshape(g, n, n, m * channels)
    layers = values.reshape(g, n, n, packed, 4).transpose(0, 3, 1, 2, 4)
    return layers.reshape(g * packed, n, n, 4), packed


def upload_btf(ctx: moderngl.Context, btf) -> BtfTextures:
    """Textures of a per-view PCA (``mean``, ``basis``, ``weights``) or global SVD
    (``eigenmaps``, ``weights``) BTF; see ``docs/material.md``."""
    n_lights = len(btf.light_dirs_deg)
    channels = (btf.eigenmaps if isinstance(btf, GlobalSVD) else btf.mean).shape[-1]
    if channels not in (1, 3):
        raise RenderError(
            f"material btf: {channels} channels per texel; the renderer shows 1 (grey) or 3 (RGB)"
        )
    if isinstance(btf, GlobalSVD):
        c = btf.eigenmaps.shape[0]
        layers, packed = _packed(np.swapaxes(np.asarray(btf.eigenmaps), 0, 1))
        weights = _rows(ctx, "btf weights", _coefficients(np.asarray(btf.weights, np.float32)))
        images = _layers(ctx, "eigenmaps", layers)
        return BtfTextures("svd", c, n_lights, channels, packed, weights, images)
    n_views, c = btf.basis.shape[:2]
    # The mean last: four basis images then fill whole texels (3 for RGB, 1 for grey).
    slots = np.concatenate([np.asarray(btf.basis), np.asarray(btf.mean)[:, None]], axis=1)
    layers, packed = _packed(slots)
    p = np.asarray(btf.weights, np.float32).reshape(n_views * n_lights, c)
    weights = _rows(ctx, "btf weights", _coefficients(p))
    images = _layers(ctx, "mean and basis", layers)
    return BtfTextures("pca", c, n_lights, channels, packed, weights, images)


@dataclass
class PsTextures:
    """Albedo and normal map (sample frame) of one photometric-stereo view."""

    albedo: moderngl.Texture
    normals: moderngl.Texture

    def release(self) -> None:
        self.albedo.release()
        self.normals.release()


def _map(ctx: moderngl.Context, image: np.ndarray) -> moderngl.Texture:
    n_rows, n_cols, channels = image.shape
    data = np.ascontiguousarray(image[::-1], dtype=np.float32)
    return material_sampling(ctx.texture((n_cols, n_rows), channels, data, dtype="f4"), channels)


def upload_ps(ctx: moderngl.Context, view) -> PsTextures:
    """Textures of a ``PsView``; texels not ``valid`` (or not finite) get the
    frontal normal and zero albedo, so they shade as black, never NaN."""
    valid = np.asarray(view.valid, bool)
    normals = np.asarray(view.normals, np.float32)
    albedo = np.asarray(view.albedo, np.float32)
    if albedo.ndim == 2:
        albedo = albedo[..., None]
    if normals.shape[:2] != valid.shape or albedo.shape[:2] != valid.shape or normals.shape[2] != 3:
        raise RenderError(
            f"ps view {view.name!r}: normals {normals.shape}, albedo {albedo.shape} and valid "
            f"{valid.shape} must share one (N, N) grid, normals with 3 components"
        )
    good = valid & np.all(np.isfinite(normals), axis=-1) & np.all(np.isfinite(albedo), axis=-1)
    normals = np.where(good[..., None], normals, np.float32([0.0, 0.0, 1.0]))
    albedo = np.where(good[..., None], albedo, 0.0).astype(np.float32)
    return PsTextures(_map(ctx, albedo), _map(ctx, normals))


def lookup_texture(ctx: moderngl.Context, lookup: DirectionLookup) -> moderngl.TextureArray:
    """The candidate grid: a float32 array texture, layer per candidate texel (see
    ``DirectionLookup.cell_texels``), read by texelFetch."""
    texels = lookup.cell_texels()
    layers, r = texels.shape[:2]
    texture = ctx.texture_array((r, r, layers), 4, texels, dtype="f4")
    texture.filter = (moderngl.NEAREST, moderngl.NEAREST)
    return texture


def light_cosine_texture(ctx: moderngl.Context, light_vectors) -> moderngl.Texture:
    """cos θ of each measured light, floored at ``rig.geometry.LIGHT_COSINE_FLOOR``: an
    (n, 1) float32 texture the light blends divide by (``carry_light_cosine`` in
    ``directions.glsl``), read by texelFetch."""
    cosines = np.maximum(np.asarray(light_vectors, np.float64)[:, 2], LIGHT_COSINE_FLOOR)
    texture = ctx.texture((len(cosines), 1), 1, cosines.astype(np.float32), dtype="f4")
    texture.filter = (moderngl.NEAREST, moderngl.NEAREST)
    return texture


@dataclass
class PbrTextures:
    """A material's PBR fit: its four map layers (``rig.material.pbr_layers``) and the
    sheen's directional-albedo table (``render/shaders/pbr.glsl``)."""

    maps: moderngl.TextureArray
    sheen: moderngl.Texture

    def release(self) -> None:
        self.maps.release()
        self.sheen.release()


def upload_pbr(ctx: moderngl.Context, maps: PbrMaps) -> PbrTextures:
    """Textures of the fitted PBR maps, sampled as the BTF is (repeating, trilinear)."""
    layers = np.ascontiguousarray(pbr_layers(maps)[:, ::-1])
    n = layers.shape[1]
    texture = material_sampling(ctx.texture_array((n, n, 4), 4, layers, dtype="f4"), 4)
    cos, rough = np.linspace(0.0, 1.0, 33), np.linspace(0.07, 1.0, 25)
    table = sheen_albedo(cos[:, None], rough[None, :]).astype(np.float32)  # rows: cos θ
    sheen = ctx.texture((len(rough), len(cos)), 1, np.ascontiguousarray(table), dtype="f4")
    sheen.filter = (moderngl.NEAREST, moderngl.NEAREST)
    return PbrTextures(texture, sheen)
