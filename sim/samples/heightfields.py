"""Height-field samples: flat, bumps, corduroy ribs, knit-like relief, image.

Each surface is ``z = h(x, y)`` in the sample frame (mm) with its highest
point at z = 0 (the reference plane) and its lowest at −``amplitude_mm``;
``flat`` is a plane at −``depth_mm`` (the recess floor).
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from rig.errors import ConfigError
from sim.materials import sample_image
from sim.samples.base import SampleGeometry, height_field_geometry, register_sample

__all__ = [
    "BumpsParams",
    "CorduroyParams",
    "FlatParams",
    "ImageHeightParams",
    "KnitParams",
]


class _HeightParams(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)
    grid: int = Field(129, ge=2, le=2049, description="mesh vertices per side")


class FlatParams(_HeightParams):
    grid: int = Field(2, ge=2, le=2049, description="mesh vertices per side")


class BumpsParams(_HeightParams):
    amplitude_mm: float = Field(1.0, gt=0)
    spacing_mm: float = Field(8.0, gt=0, description="lattice pitch of the bumps")
    sigma_mm: float = Field(1.5, gt=0, description="Gaussian width of a bump, ≤ spacing/4")


class CorduroyParams(_HeightParams):
    amplitude_mm: float = Field(1.0, gt=0)
    pitch_mm: float = Field(4.0, gt=0, description="distance between ribs (along x)")
    roundness: float = Field(1.5, ge=1, description="exponent q of |sin|^q; larger is sharper")


class KnitParams(_HeightParams):
    amplitude_mm: float = Field(1.0, gt=0)
    wale_mm: float = Field(5.0, gt=0, description="stitch width (along x)")
    course_mm: float = Field(4.0, gt=0, description="stitch height (along y)")
    leg_angle_deg: float = Field(25.0, ge=0, lt=80, description="lean of a stitch's legs")
    yarn_mm: float = Field(0.8, gt=0, description="Gaussian half-width of a leg")


class ImageHeightParams(_HeightParams):
    path: Path = Field(description="grey image; white is high, black low")
    amplitude_mm: float = Field(1.0, gt=0)


def _wrap(u: np.ndarray, period: float) -> np.ndarray:
    """Distance to the nearest lattice line at multiples of ``period`` (signed)."""
    return u - period * np.round(u / period)


@register_sample("flat", FlatParams)
def _flat(params: FlatParams, *, sample_mm: float, depth_mm: float) -> SampleGeometry:
    def h(x, y):
        return np.full_like(np.asarray(x, dtype=np.float64), -depth_mm)

    return height_field_geometry(h, sample_mm=sample_mm, grid=params.grid, depth_mm=depth_mm)


@register_sample("bumps", BumpsParams)
def _bumps(params: BumpsParams, *, sample_mm: float, depth_mm: float) -> SampleGeometry:
    if params.sigma_mm > params.spacing_mm / 4:
        raise ConfigError(
            f"sample.params.sigma_mm: {params.sigma_mm} mm is more than spacing_mm/4 "
            f"({params.spacing_mm / 4} mm); bumps would be cut at the lattice cells"
        )
    a, p, s = params.amplitude_mm, params.spacing_mm, params.sigma_mm

    def h(x, y):
        r2 = _wrap(x - p / 2, p) ** 2 + _wrap(y - p / 2, p) ** 2
        return -a + a * np.exp(-r2 / (2 * s * s))

    return height_field_geometry(h, sample_mm=sample_mm, grid=params.grid, depth_mm=depth_mm)


@register_sample("corduroy", CorduroyParams)
def _corduroy(params: CorduroyParams, *, sample_mm: float, depth_mm: float) -> SampleGeometry:
    a, p, q = params.amplitude_mm, params.pitch_mm, params.roundness

    def h(x, y):
        return -a + a * np.abs(np.sin(np.pi * np.asarray(x) / p)) ** q + 0 * np.asarray(y)

    return height_field_geometry(h, sample_mm=sample_mm, grid=params.grid, depth_mm=depth_mm)


@register_sample("knit", KnitParams)
def _knit(params: KnitParams, *, sample_mm: float, depth_mm: float) -> SampleGeometry:
    a, pw, pc = params.amplitude_mm, params.wale_mm, params.course_mm
    lean = np.tan(np.deg2rad(params.leg_angle_deg))
    w = params.yarn_mm

    def h(x, y):
        u = _wrap(np.asarray(x, dtype=np.float64), pw)  # −pw/2 … pw/2 across the stitch
        v = np.mod(y, pc) / pc  # 0 … 1 up the stitch
        offset = (v - 0.5) * pc * lean
        # Each V stitch: two leaning legs, fading at the stitch ends so
        # neighbouring courses join smoothly (a loop-like relief).
        fade = np.sin(np.pi * v) ** 2
        left = np.exp(-((u + pw / 4 + offset) ** 2) / (2 * w * w))
        right = np.exp(-((u - pw / 4 - offset) ** 2) / (2 * w * w))
        f = 1 - (1 - fade * left) * (1 - fade * right)
        return -a + a * f

    return height_field_geometry(h, sample_mm=sample_mm, grid=params.grid, depth_mm=depth_mm)


@register_sample("image", ImageHeightParams)
def _image(params: ImageHeightParams, *, sample_mm: float, depth_mm: float) -> SampleGeometry:
    img = cv2.imread(str(params.path), cv2.IMREAD_GRAYSCALE | cv2.IMREAD_ANYDEPTH)
    if img is None:
        raise ConfigError(f"sample.params.path: cannot read height image {params.path}")
    img = img.astype(np.float64)
    span = float(img.max() - img.min())
    img = (img - img.min()) / span if span > 0 else np.ones_like(img)
    a = params.amplitude_mm

    def h(x, y):
        xy = np.column_stack([np.ravel(x), np.ravel(y)])
        z = sample_image(img, xy, sample_mm, order=3)
        return (-a + a * np.clip(z, 0, 1)).reshape(np.shape(x))

    return height_field_geometry(h, sample_mm=sample_mm, grid=params.grid, depth_mm=depth_mm)
