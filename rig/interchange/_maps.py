"""The photometric-stereo material as the texture set DCC tools and game engines read.

- ``albedo.png``: diffuse albedo, 8-bit sRGB (reflectance 1 → 255 unless the
  manifest's ``albedo_white`` says otherwise);
- ``normal.png``: tangent-space normal map, 16-bit, OpenGL convention (+X
  right, +Y up in the image, RGB = (n + 1) / 2): on the flat sample the
  sample frame is the tangent frame, since the texel grid has row 0 at +y and
  column 0 at −x (``rig.geometry.texel_centers_mm``);
- ``height.png`` (16-bit) and ``height.exr`` (float, mm): height over the
  reference plane; ``height_mm = height_min_mm + count × mm_per_count``;
- ``valid.png``: 255 where the solve was trustworthy.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rig.interchange._errors import InterchangeError
from rig.interchange._images import to_srgb, write_exr, write_image
from rig.interchange._manifest import write_manifest
from rig.material import PsView

__all__ = ["TextureMaps", "decode_normal_map", "texture_maps", "write_maps"]

_FULL16 = 65535.0


@dataclass(frozen=True)
class TextureMaps:
    """The maps of one PS view, encoded for files.

    Attributes
    ----------
    albedo : (N, N, 3) uint8, sRGB
    normal : (N, N, 3) uint16, OpenGL-convention tangent-space normal map
    height : (N, N) uint16
    height_mm : (N, N) float32
    valid : (N, N) bool
    albedo_white : float
        Albedo written as 255.
    height_min_mm, mm_per_count : float
        ``height_mm ≈ height_min_mm + height × mm_per_count`` (0 for a flat map).
    """

    albedo: np.ndarray
    normal: np.ndarray
    height: np.ndarray
    height_mm: np.ndarray
    valid: np.ndarray
    albedo_white: float
    height_min_mm: float
    mm_per_count: float


def texture_maps(view: PsView) -> TextureMaps:
    """Encode a PS view's maps. Invalid texels get the flat normal (0, 0, 1) and
    black albedo; their height stays the integrated one."""
    valid = np.asarray(view.valid, bool)
    normals = np.nan_to_num(np.asarray(view.normals, np.float64))
    length = np.linalg.norm(normals, axis=2, keepdims=True)
    usable = valid[..., None] & (length > 0.5)
    normals = np.where(usable, normals / np.maximum(length, 1e-12), [0.0, 0.0, 1.0])
    normal = np.round((np.clip(normals, -1, 1) + 1.0) * 0.5 * _FULL16).astype(np.uint16)
    albedo = np.nan_to_num(np.asarray(view.albedo, np.float64))
    if albedo.shape[2] == 1:
        albedo = np.repeat(albedo, 3, axis=2)
    albedo = np.where(valid[..., None], albedo, 0.0)
    white = max(1.0, float(albedo.max()))  # no clipping of a brighter-than-white albedo
    height_mm = np.nan_to_num(np.asarray(view.height_mm, np.float64))
    low, high = float(height_mm.min()), float(height_mm.max())
    step = (high - low) / _FULL16
    counts = np.zeros(height_mm.shape) if step == 0 else (height_mm - low) / step
    return TextureMaps(
        albedo=to_srgb(albedo / white), normal=normal,
        height=np.round(counts).astype(np.uint16), height_mm=height_mm.astype(np.float32),
        valid=valid, albedo_white=white, height_min_mm=low, mm_per_count=step,
    )  # fmt: skip


def decode_normal_map(normal) -> np.ndarray:
    """Unit normals (tangent frame = sample frame) of an OpenGL-convention normal map,
    ``(N, N, 3)`` uint8 or uint16 → float64."""
    normal = np.asarray(normal)
    if normal.ndim != 3 or normal.shape[2] != 3 or normal.dtype.kind != "u":
        raise InterchangeError(
            f"normal map: expected (N, N, 3) uint8 or uint16, got {normal.dtype} {normal.shape}"
        )
    vectors = normal / float(np.iinfo(normal.dtype).max) * 2.0 - 1.0
    return vectors / np.maximum(np.linalg.norm(vectors, axis=2, keepdims=True), 1e-12)


def write_maps(out, maps: TextureMaps, *, sample_mm: float, manifest: dict) -> Path:
    """Write the maps into the existing folder ``out``; returns the manifest's path."""
    out = Path(out)
    write_image(out / "albedo.png", maps.albedo)
    write_image(out / "normal.png", maps.normal)
    write_image(out / "height.png", maps.height)
    write_exr(out / "height.exr", maps.height_mm)
    write_image(out / "valid.png", np.where(maps.valid, 255, 0).astype(np.uint8))
    size = maps.normal.shape[0]
    document = {
        **manifest,
        "sample_mm": float(sample_mm), "texels": size, "texel_mm": float(sample_mm) / size,
        "albedo": {"file": "albedo.png", "encoding": "srgb", "albedo_white": maps.albedo_white},
        "normal": {"file": "normal.png", "bits": 16, "convention": "OpenGL (+Y up)",
                   "tangent_frame": "x = image right (+u), y = image up, z = out of the surface",
                   "decode": "n = 2 · value / 65535 − 1"},
        "height": {"file": "height.png", "bits": 16, "float_file": "height.exr",
                   "height_min_mm": maps.height_min_mm, "mm_per_count": maps.mm_per_count,
                   "height_max_mm": maps.height_min_mm + _FULL16 * maps.mm_per_count,
                   "decode": "height_mm = height_min_mm + value × mm_per_count"},
        "valid": {"file": "valid.png", "valid_texels": int(maps.valid.sum())},
    }  # fmt: skip
    return write_manifest(out, document)
