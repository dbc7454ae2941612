"""Analytic laser scans with a known answer, for tests and ``rig bench mdf``.

A recessed height-field sample (sinusoidal ribs and Gaussian bumps, z ≤ 0) in a
flat holder plate at z = 0, seen by a pinhole camera and scanned by laser
sheets. Each pixel's first surface hit is found by ray marching with bisection
on the analytic height field; a pixel is lit in a frame by a Gaussian sheet
profile around that frame's plane, if the emitter sees its point. None of this
uses the reconstruction code, so it is an independent ground truth. (The full
simulator in ``sim/`` renders meshes with effects; processing may not import it,
and benches must run without it.)
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from rig.camera import PinholeCamera
from rig.config import RigConfig
from rig.kinematics import laser_plane, laser_source_mm

__all__ = [
    "RibbedSample",
    "SyntheticScan",
    "first_hit",
    "render_scan",
    "rig_scan",
    "true_distance",
    "visible_from",
]

_FLOOR = -1.0e6  # beyond the plate: nothing to hit


@dataclass(frozen=True)
class RibbedSample:
    """A height field in a square recess of a flat plate (sample frame, mm).

    ``z = base + rib_amplitude·cos(2πx/rib_period) + Σ bump_height·exp(-r²/2σ²)``
    inside the sample square, 0 on the plate, nothing beyond the plate.
    """

    sample_mm: float = 100.0
    plate_mm: float = 180.0
    base_mm: float = -2.0
    rib_amplitude_mm: float = 0.8
    rib_period_mm: float = 25.0
    bumps: tuple[tuple[float, float, float, float], ...] = (
        (-20.0, 15.0, 6.0, 1.0),
        (18.0, -22.0, 5.0, 0.9),
        (10.0, 25.0, 7.0, -0.8),
    )

    @property
    def lowest_mm(self) -> float:
        """A bound below the lowest surface point."""
        dips = sum(min(h, 0.0) for *_, h in self.bumps)
        return self.base_mm - self.rib_amplitude_mm + dips - 0.5

    def height(self, x, y) -> np.ndarray:
        """Surface height at (x, y), broadcast; -1e6 beyond the plate."""
        x, y = np.broadcast_arrays(np.asarray(x, np.float64), np.asarray(y, np.float64))
        z = self.base_mm + self.rib_amplitude_mm * np.cos(2 * np.pi * x / self.rib_period_mm)
        for bx, by, sigma, h in self.bumps:
            z = z + h * np.exp(-((x - bx) ** 2 + (y - by) ** 2) / (2 * sigma**2))
        half, plate = self.sample_mm / 2, self.plate_mm / 2
        in_sample = (np.abs(x) < half) & (np.abs(y) < half)
        on_plate = (np.abs(x) <= plate) & (np.abs(y) <= plate)
        return np.where(in_sample, np.minimum(z, 0.0), np.where(on_plate, 0.0, _FLOOR))

    def albedo(self, x, y) -> np.ndarray:
        """A smooth albedo texture in [0.45, 0.95] on the sample, 0.8 on the plate."""
        half = self.sample_mm / 2
        in_sample = (np.abs(x) < half) & (np.abs(y) < half)
        return np.where(in_sample, 0.7 + 0.25 * np.sin(x / 7.0) * np.cos(y / 5.0), 0.8)


def first_hit(
    origin, directions, sample: RibbedSample, *, step_mm: float = 0.05
) -> tuple[np.ndarray, np.ndarray]:
    """First intersection of rays with the sample and plate.

    Returns
    -------
    points : (n, 3) float64 (zeros where no hit)
    hit : (n,) bool
    """
    o = np.asarray(origin, np.float64)
    d = np.asarray(directions, np.float64).reshape(-1, 3)
    down = d[:, 2] < -1e-9
    dz = np.where(down, d[:, 2], -1.0)
    t0 = np.where(down, -o[2] / dz, 0.0)
    t1 = np.where(down, (sample.lowest_mm - o[2]) / dz, 0.0)
    n_steps = int(np.ceil(np.max(t1 - t0) / step_mm)) + 1

    def below(t):  # the ray point at t is inside the solid
        p = o + t[:, None] * d
        return p[:, 2] <= sample.height(p[:, 0], p[:, 1])

    hit = np.zeros(len(d), bool)
    t_hi = t1.copy()
    t_lo = t0.copy()
    for k in range(n_steps):
        t = np.minimum(t0 + k * step_mm, t1)
        new = down & ~hit & below(t)
        t_hi = np.where(new, t, t_hi)
        t_lo = np.where(new, np.maximum(t - step_mm, t0), t_lo)
        hit |= new
    at_top = hit & (t_hi == t0)
    for _ in range(40):
        mid = 0.5 * (t_lo + t_hi)
        inside = below(mid)
        t_hi = np.where(inside, mid, t_hi)
        t_lo = np.where(inside, t_lo, mid)
    t_hit = np.where(at_top, t0, t_hi)
    points = np.where(hit[:, None], o + t_hit[:, None] * d, 0.0)
    return points, hit


def visible_from(points, source_mm, sample: RibbedSample, *, step_mm: float = 0.05) -> np.ndarray:
    """(n,) bool: the segment from each point towards the source stays outside the solid."""
    p = np.asarray(points, np.float64).reshape(-1, 3)
    s = np.asarray(source_mm, np.float64)
    d = s - p
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    rise = np.maximum(d[:, 2], 1e-6)
    length = np.minimum(-p[:, 2] / rise, 1e4)  # up to z = 0, above which nothing blocks
    free = np.ones(len(p), bool)
    n_steps = int(np.ceil(np.max(length, initial=0.0) / step_mm)) + 1
    for k in range(1, n_steps + 1):
        t = np.minimum(k * step_mm, length)
        q = p + t[:, None] * d
        free &= ~((t > 0.02) & (q[:, 2] < sample.height(q[:, 0], q[:, 1]) - 1e-6))
    return free


def true_distance(camera: PinholeCamera, sample: RibbedSample, texels_xy) -> np.ndarray:
    """Ground-truth MDF of one perspective view: distance along the ray from the
    camera through (x, y, 0) to the first hit, mm. Shape of ``texels_xy[..., 0]``."""
    xy = np.asarray(texels_xy, np.float64)
    q = np.column_stack([xy.reshape(-1, 2), np.zeros(xy[..., 0].size)])
    c = camera.center
    d = (q - c) / np.linalg.norm(q - c, axis=1, keepdims=True)
    points, _ = first_hit(c, d, sample)
    return np.linalg.norm(points - q, axis=1).reshape(xy.shape[:-1])


@dataclass(frozen=True)
class SyntheticScan:
    """The true laser planes of one scan (sample frame).

    ``normal`` (F, 3), ``offset`` (F,): planes ``n · x = offset``; ``source_mm``
    (3,): the emitter; ``angle_deg`` (F,): each plane's angle to z = 0.
    """

    normal: np.ndarray
    offset: np.ndarray
    source_mm: np.ndarray
    angle_deg: np.ndarray


def rig_scan(
    config: RigConfig,
    *,
    arc_deg: float,
    mount: int = 0,
    turntable_deg: float = 0.0,
    step_deg: float | None = None,
    sweep_deg: float | None = None,
) -> SyntheticScan:
    """The planes of a scan on a rig, from ``rig.kinematics.laser_plane``.

    The emitter tilts from ``-sweep/2`` to ``+sweep/2`` in steps of ``step_deg``
    (defaults: the config's sweep, and its sweep speed / frame rate).
    """
    laser = config.laser
    step = laser.sweep_speed_deg_s / laser.frame_rate_hz if step_deg is None else step_deg
    sweep = laser.sweep_deg if sweep_deg is None else sweep_deg
    tilts = np.arange(-sweep / 2, sweep / 2 + 1e-9, step)
    planes = [
        laser_plane(config, arc_deg=arc_deg, mount=mount, tilt_deg=t, turntable_deg=turntable_deg)
        for t in tilts
    ]
    normal = np.array([n for n, _ in planes])
    return SyntheticScan(
        normal=normal,
        offset=np.array([d for _, d in planes]),
        source_mm=laser_source_mm(config, mount, arc_deg=arc_deg, turntable_deg=turntable_deg),
        angle_deg=np.rad2deg(np.arccos(np.clip(normal[:, 2], -1, 1))),
    )


def render_scan(
    camera: PinholeCamera,
    sample: RibbedSample,
    scan: SyntheticScan,
    *,
    sheet_sigma_mm: float = 1.0,
    peak: float = 200.0,
    ambient: float = 10.0,
    noise_sigma: float = 1.0,
    seed: int = 0,
) -> Iterator[np.ndarray]:
    """The 8-bit frames of a scan, one (H, W) uint8 image per plane.

    A pixel shows ``albedo · (ambient + peak · exp(-dist²/2σ²))`` plus Gaussian
    noise, ``dist`` being its surface point's distance to the frame's plane,
    when the emitter sees the point (else ambient only); pixels that see
    nothing beyond the plate are black.
    """
    h, w = camera.height, camera.width
    rows, cols = np.mgrid[0:h, 0:w]
    origin, dirs = camera.rays(np.column_stack([cols.ravel(), rows.ravel()]))
    points, hit = first_hit(origin, dirs, sample)
    lit = hit & visible_from(points, scan.source_mm, sample)
    albedo = np.where(hit, sample.albedo(points[:, 0], points[:, 1]), 0.0)
    rng = np.random.default_rng(seed)
    for n, c in zip(scan.normal, scan.offset, strict=True):
        dist = points @ n - c
        sheet = np.where(lit, np.exp(-(dist**2) / (2 * sheet_sigma_mm**2)), 0.0)
        value = albedo * (ambient + peak * sheet) + rng.normal(0.0, noise_sigma, albedo.shape)
        yield np.clip(np.rint(value), 0, 255).astype(np.uint8).reshape(h, w)
