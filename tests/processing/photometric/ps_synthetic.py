"""A synthetic photometric-stereo renderer with an analytic answer.

Independent of the package under test: it writes out the Lambertian model,
the near-lamp geometry and the surface gradients itself.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Surface:
    """A height field of Gaussian bumps on an n×n grid (row 0 at +y, column 0 at -x)."""

    x: np.ndarray  # (H, W) mm
    y: np.ndarray  # (H, W) mm
    height: np.ndarray  # (H, W) mm
    normals: np.ndarray  # (H, W, 3)
    albedo: np.ndarray  # (H, W)
    pitch_mm: float


def bumps(n=64, *, pitch_mm=0.1, amplitude_mm=0.6, seed=0, n_bumps=6, sigma_px=(5.0, 9.0)):
    """Sum of Gaussian bumps kept away from the border (so it is ~flat there)."""
    rng = np.random.default_rng(seed)
    coords = (np.arange(n) - (n - 1) / 2) * pitch_mm
    x, y = np.meshgrid(coords, coords[::-1])
    height = np.zeros((n, n))
    hx = np.zeros((n, n))
    hy = np.zeros((n, n))
    half = (n - 1) / 2 * pitch_mm
    for _ in range(n_bumps):
        s = rng.uniform(*sigma_px) * pitch_mm
        cx, cy = rng.uniform(-half + 3.5 * s, half - 3.5 * s, size=2)
        a = rng.uniform(-1, 1) * amplitude_mm * s / (sigma_px[1] * pitch_mm)
        g = a * np.exp(-((x - cx) ** 2 + (y - cy) ** 2) / (2 * s * s))
        height += g
        hx += -g * (x - cx) / (s * s)
        hy += -g * (y - cy) / (s * s)
    normals = np.stack([-hx, -hy, np.ones_like(hx)], axis=-1)
    normals /= np.linalg.norm(normals, axis=-1, keepdims=True)
    albedo = 0.3 + 0.5 * rng.random((n, n))
    return Surface(x, y, height, normals, albedo, pitch_mm)


def ring_directions(n_lights, *, theta_deg=(20, 40, 60), phase_deg=7.0):
    """Lights on rings of polar angle, evenly spread in azimuth."""
    per_ring = np.diff(np.linspace(0, n_lights, len(theta_deg) + 1).round().astype(int))
    dirs = []
    for k, (theta, count) in enumerate(zip(theta_deg, per_ring, strict=True)):
        phi = np.deg2rad(phase_deg + k * 17.0 + 360.0 * np.arange(count) / count)
        t = np.deg2rad(theta)
        dirs.append(
            np.stack(
                [np.sin(t) * np.cos(phi), np.sin(t) * np.sin(phi), np.full(count, np.cos(t))],
                axis=1,
            )
        )
    return np.concatenate(dirs)


def render_distant(surface, directions, intensities=None):
    """(L, H, W) Lambertian images, attached shadows clamped at 0."""
    s = directions if intensities is None else directions * np.asarray(intensities)[:, None]
    shading = np.einsum("li,hwi->lhw", s, surface.normals)
    return surface.albedo * np.clip(shading, 0, None)


def render_near(surface, positions_mm, intensities=None):
    """(L, H, W) Lambertian images under point lamps with 1/r² falloff."""
    points = np.stack([surface.x, surface.y, surface.height], axis=-1)
    out = []
    power = np.ones(len(positions_mm)) if intensities is None else np.asarray(intensities)
    for lamp, p in zip(positions_mm, power, strict=True):
        d = lamp - points
        r = np.sqrt((d**2).sum(-1))
        cos = np.clip((d * surface.normals).sum(-1) / r, 0, None)
        out.append(surface.albedo * p * (lamp @ lamp) / r**2 * cos)
    return np.stack(out)


def specular(surface, directions, *, strength=1.5, exponent=60.0):
    """(L, H, W) Blinn-Phong highlights for a camera looking straight down."""
    half = directions + np.array([0.0, 0.0, 1.0])
    half /= np.linalg.norm(half, axis=1, keepdims=True)
    cos = np.clip(np.einsum("li,hwi->lhw", half, surface.normals), 0, None)
    lit = np.einsum("li,hwi->lhw", directions, surface.normals) > 0
    return strength * cos**exponent * lit


def angular_error_deg(a, b):
    """Angle between normals, degrees (atan2 form: exact near 0, unlike arccos)."""
    a = np.asarray(a, np.float64)
    b = np.asarray(b, np.float64)
    cross = np.linalg.norm(np.cross(a, b), axis=-1)
    return np.degrees(np.arctan2(cross, (a * b).sum(-1)))
