"""Materials of a scene: albedo textures and exact reflectance models.

A material is Lambertian with a spatially varying albedo ρ(x, y), plus an
optional specular lobe:

- Phong (energy-normalised): ``f_s = k_s (n + 2) / (2π) · max(0, r·v)^n`` with
  ``r`` the mirror direction of the light about the normal.
- Lafortune et al. 1997 (the lobe model named in seed ``003_…``):
  ``f_s = Σ ρ_j · max(0, C_x,j l_x v_x + C_y,j l_y v_y + C_z,j l_z v_z)^n_j``
  in the local frame (tangent along the sample's x axis, normal as z).

Textures are mapped planarly onto the sample square ``[-s/2, s/2]²`` of the
sample frame; an image's row 0 lies at +y and column 0 at −x (the texel-grid
convention of :func:`rig.geometry.texel_centers_mm`).
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path
from typing import Annotated, Literal

import cv2
import numpy as np
from pydantic import BaseModel, ConfigDict, Field
from scipy.ndimage import map_coordinates

from rig.errors import ConfigError

__all__ = [
    "Albedo",
    "CheckerAlbedo",
    "ConstantAlbedo",
    "ImageAlbedo",
    "LafortuneLobe",
    "LafortuneSpecular",
    "MaterialSpec",
    "NoiseAlbedo",
    "PhongSpecular",
    "Specular",
    "eval_albedo",
    "eval_specular",
    "specular_view_terms",
]

Unit = Annotated[float, Field(ge=0, le=1)]
RGB = tuple[Unit, Unit, Unit]


class _Closed(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class ConstantAlbedo(_Closed):
    kind: Literal["constant"] = "constant"
    rgb: RGB = (0.7, 0.7, 0.7)


class CheckerAlbedo(_Closed):
    kind: Literal["checker"]
    rgb_a: RGB = (0.8, 0.8, 0.8)
    rgb_b: RGB = (0.2, 0.2, 0.2)
    period_mm: float = Field(10.0, gt=0, description="side of one checker square")


class NoiseAlbedo(_Closed):
    """Smooth procedural variation: a sum of random plane waves around ``rgb``."""

    kind: Literal["noise"]
    rgb: RGB = (0.6, 0.5, 0.4)
    variation: float = Field(0.3, ge=0, le=1, description="relative amplitude")
    scale_mm: float = Field(5.0, gt=0, description="typical feature size")
    seed: int = 0


class ImageAlbedo(_Closed):
    """An image file stretched over the sample square (values taken as linear)."""

    kind: Literal["image"]
    path: Path
    gain: float = Field(1.0, gt=0, description="albedo = gain · pixel / max value, ≤ 1")


Albedo = Annotated[
    ConstantAlbedo | CheckerAlbedo | NoiseAlbedo | ImageAlbedo, Field(discriminator="kind")
]


class PhongSpecular(_Closed):
    model: Literal["phong"]
    ks: float = Field(0.2, ge=0, le=1, description="specular albedo")
    exponent: float = Field(40.0, gt=0)


class LafortuneLobe(_Closed):
    cx: float = -1.0
    cy: float = -1.0
    cz: float = 1.0
    n: float = Field(20.0, gt=0)
    rho: float = Field(0.2, ge=0)


class LafortuneSpecular(_Closed):
    model: Literal["lafortune"]
    lobes: tuple[LafortuneLobe, ...] = Field((LafortuneLobe(),), min_length=1)


Specular = Annotated[PhongSpecular | LafortuneSpecular, Field(discriminator="model")]


class MaterialSpec(_Closed):
    """One material: Lambertian albedo texture and an optional specular lobe."""

    albedo: Albedo = ConstantAlbedo()
    specular: Specular | None = None


@lru_cache(maxsize=8)
def _load_image(path: str) -> np.ndarray:
    img = cv2.imread(path, cv2.IMREAD_UNCHANGED)
    if img is None:
        raise ConfigError(f"albedo image {path} cannot be read (missing or not an image)")
    img = img.astype(np.float64) / (65535.0 if img.dtype == np.uint16 else 255.0)
    if img.ndim == 2:
        img = np.repeat(img[..., None], 3, axis=2)
    img = img[..., 2::-1] if img.shape[2] >= 3 else img  # BGR(A) → RGB
    img.setflags(write=False)
    return img


def sample_image(img: np.ndarray, xy: np.ndarray, sample_mm: float, *, order: int) -> np.ndarray:
    """Values of an image stretched over the sample square at points (n, 2) mm.

    ``order`` is the spline order (1 bilinear, 3 bicubic); edges clamp.
    """
    h, w = img.shape[:2]
    col = (xy[:, 0] / sample_mm + 0.5) * w - 0.5
    row = (0.5 - xy[:, 1] / sample_mm) * h - 0.5
    coords = np.stack([row, col])
    if img.ndim == 2:
        return map_coordinates(img, coords, order=order, mode="nearest")
    return np.stack(
        [map_coordinates(img[..., c], coords, order=order, mode="nearest") for c in range(3)],
        axis=1,
    )


def eval_albedo(spec: Albedo, xy: np.ndarray, *, sample_mm: float) -> np.ndarray:
    """Albedo (n, 3) float64 in [0, 1] at sample-frame points ``xy`` (n, 2) mm."""
    n = len(xy)
    if isinstance(spec, ConstantAlbedo):
        return np.broadcast_to(np.array(spec.rgb), (n, 3)).copy()
    if isinstance(spec, CheckerAlbedo):
        cell = np.floor(xy / spec.period_mm).astype(np.int64).sum(axis=1) % 2
        return np.where(cell[:, None] == 0, np.array(spec.rgb_a), np.array(spec.rgb_b))
    if isinstance(spec, NoiseAlbedo):
        rng = np.random.default_rng(spec.seed)
        k = 8
        angles = rng.uniform(0, np.pi, k)
        freqs = 2 * np.pi / (spec.scale_mm * rng.uniform(0.7, 1.4, k))
        phases = rng.uniform(0, 2 * np.pi, k)
        dirs = np.stack([np.cos(angles), np.sin(angles)], axis=1) * freqs[:, None]
        wave = np.sin(xy @ dirs.T + phases).sum(axis=1) / np.sqrt(k / 2)
        factor = np.clip(1 + spec.variation * np.tanh(wave), 0, None)
        return np.clip(np.array(spec.rgb)[None, :] * factor[:, None], 0, 1)
    img = _load_image(str(spec.path))
    return np.clip(spec.gain * sample_image(img, xy, sample_mm, order=1), 0, 1)


def specular_view_terms(spec: Specular, normals: np.ndarray, view_dirs: np.ndarray) -> dict:
    """The parts of :func:`eval_specular` that depend on the view only, (n,) arrays.

    ``cos_v``, and for Lafortune lobes the local frame (``t``, ``b``) and the
    view in it (``vx``, ``vy``): computed once per set of hits and reused for
    every lamp that lights them.
    """
    terms = {"cos_v": np.einsum("ij,ij->i", normals, view_dirs)}
    if isinstance(spec, PhongSpecular):
        return terms
    # Local frame: tangent = sample x projected onto the tangent plane.
    ex = np.array([1.0, 0.0, 0.0])
    t = ex - normals * normals[:, :1]
    bad = np.linalg.norm(t, axis=1) < 1e-6
    t[bad] = np.cross(normals[bad], [0.0, 1.0, 0.0]) if bad.any() else t[bad]
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    b = np.cross(normals, t)
    vx, vy = np.einsum("ij,ij->i", t, view_dirs), np.einsum("ij,ij->i", b, view_dirs)
    return {**terms, "t": t, "b": b, "vx": vx, "vy": vy}


def eval_specular(
    spec: Specular,
    normals: np.ndarray,
    light_dirs: np.ndarray,
    view_dirs: np.ndarray,
    view_terms: dict | None = None,
) -> np.ndarray:
    """Specular BRDF value (n,) float64, 1/sr, for unit vectors (n, 3).

    Zero where the light or the view is below the local surface.
    ``view_terms``: :func:`specular_view_terms` of these normals and views,
    when the caller keeps them (computed here otherwise).
    """
    if view_terms is None:
        view_terms = specular_view_terms(spec, normals, view_dirs)
    cos_l = np.einsum("ij,ij->i", normals, light_dirs)
    cos_v = view_terms["cos_v"]
    front = (cos_l > 0) & (cos_v > 0)
    if isinstance(spec, PhongSpecular):
        mirror = 2 * cos_l[:, None] * normals - light_dirs
        r_dot_v = np.clip(np.einsum("ij,ij->i", mirror, view_dirs), 0, None)
        f = spec.ks * (spec.exponent + 2) / (2 * np.pi) * r_dot_v**spec.exponent
        return np.where(front, f, 0.0)
    t, b = view_terms["t"], view_terms["b"]
    lx, ly = np.einsum("ij,ij->i", t, light_dirs), np.einsum("ij,ij->i", b, light_dirs)
    vx, vy = view_terms["vx"], view_terms["vy"]
    f = np.zeros(len(normals))
    for lobe in spec.lobes:
        base = lobe.cx * lx * vx + lobe.cy * ly * vy + lobe.cz * cos_l * cos_v
        f += lobe.rho * np.clip(base, 0, None) ** lobe.n
    return np.where(front, f, 0.0)
