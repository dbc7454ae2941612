"""Resampling a frame onto the shared texel grid: the normtexture.

Each texel of the N×N grid ``rig.geometry.texel_centers_mm(sample_mm, N)`` is
mapped through the plane → image homography (and the lens distortion) into the
raw frame and sampled there with sub-pixel (bilinear or cubic) interpolation.
When the grid minifies the frame (a texel covers more than one pixel), each
texel is supersampled on an s_x × s_y sub-grid chosen from the largest texel
footprint in pixels and the samples are averaged: a box filter, so fine
detail does not alias. The box's interpolated samples still reach half a pixel
past the texel's edge (the bilinear tent): a texel of three pixels takes a
third of its value from its neighbours' pixels.

``filter="area"`` weighs every pixel by the fraction of the texel's footprint
it covers instead: each pixel a square of constant value (what a sensor that
integrates over its pixel records), the footprint sampled at
:data:`AREA_SAMPLES_PER_PIXEL` points per pixel side, each point taking the
pixel it falls in. The weights converge on the exact overlap areas as 1/that
density; nothing outside the footprint contributes.

References
----------
.. [1] Sattler, Sarlette, Klein. "Efficient and realistic visualization of
   cloth." EGSR 2003, §3.2 (normtextures, region of interest, edge blending).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from processing.registration._errors import RegistrationError
from processing.registration._homography import PlaneHomography, distort_px
from processing.registration._sampling import (
    box_bilinear,
    homography_footprint_px,
    project_box_bilinear,
)
from rig.camera import PinholeCamera
from rig.geometry import texel_centers_mm

__all__ = [
    "AREA_SAMPLES_PER_PIXEL",
    "FILTERS",
    "Normtexture",
    "Region",
    "blend_edges",
    "rectify",
    "subgrid",
]

_MAX_SAMPLES_PER_STRIP = 1 << 20

#: The resampling filters: the box of interpolated samples, and pixel-area weights.
FILTERS = ("box", "area")

#: ``filter="area"``: footprint samples per pixel side (the area weights' resolution).
AREA_SAMPLES_PER_PIXEL = 4

#: ``filter="area"``: the most footprint samples per texel side.
_MAX_AREA_SAMPLES = 64


@dataclass(frozen=True)
class Region:
    """A square region of interest on the reference plane (sample frame, mm).

    ``center_mm`` (x, y) and ``side_mm``; the texel grid is the shared one of a
    square of that side, shifted to the centre.
    """

    center_mm: tuple[float, float]
    side_mm: float

    def __post_init__(self) -> None:
        c = np.asarray(self.center_mm, dtype=np.float64)
        if c.shape != (2,) or not np.all(np.isfinite(c)):
            raise RegistrationError(f"Region.center_mm = {self.center_mm}: need finite (x, y)")
        if not np.isfinite(self.side_mm) or self.side_mm <= 0:
            raise RegistrationError(f"Region.side_mm = {self.side_mm}: must be > 0")


@dataclass(frozen=True)
class Normtexture:
    """A frame rectified onto the texel grid.

    Attributes
    ----------
    texture : (N, N, C) float32
        Frame values (same units as the frame; C = 1 or 3) at the texels;
        0 where not ``valid``.
    valid : (N, N) bool
        False where a texel's footprint leaves the frame.
    supersample : (2,) int
        Sub-samples per texel along x and y that were averaged.
    """

    texture: np.ndarray
    valid: np.ndarray
    supersample: tuple[int, int]


def _as_frame(frame) -> np.ndarray:
    image = np.asarray(frame)
    if image.ndim == 2:
        image = image[:, :, None]
    if image.ndim != 3 or image.shape[2] not in (1, 3) or min(image.shape[:2]) < 2:
        raise RegistrationError(
            f"frame: expected an (H, W), (H, W, 1) or (H, W, 3) image, got shape {np.shape(frame)}"
        )
    if not (np.issubdtype(image.dtype, np.integer) or np.issubdtype(image.dtype, np.floating)):
        raise RegistrationError(f"frame: expected an integer or float image, got {image.dtype}")
    return image


def _to_pixels(H: np.ndarray, xy_mm: np.ndarray, camera: PinholeCamera | None) -> np.ndarray:
    """Raw pixel positions (n, 2) of plane points ``xy_mm`` (n, 2) through H and the lens.

    Written out per coordinate: a (n, 3) @ (3, 3) product goes through BLAS,
    whose threads cost several times the arithmetic on a shared machine.
    """
    x, y = xy_mm[:, 0], xy_mm[:, 1]
    w = H[2, 0] * x + H[2, 1] * y + H[2, 2]
    pix = np.empty((len(xy_mm), 2))
    pix[:, 0] = (H[0, 0] * x + H[0, 1] * y + H[0, 2]) / w
    pix[:, 1] = (H[1, 0] * x + H[1, 1] * y + H[1, 2]) / w
    return distort_px(pix, camera)


def _footprint_px(H, grid: np.ndarray, step: float, camera) -> tuple[float, float]:
    """Largest extent in pixels of one texel step along x and along y over the grid."""
    pts = grid.reshape(-1, 2)
    n = len(pts)
    # One pass over the centres and their two neighbours: the lens model once.
    shifted = np.concatenate([pts, pts + np.array([step, 0.0]), pts + np.array([0.0, step])])
    pix = _to_pixels(H, shifted, camera)
    along_x, along_y = pix[n : 2 * n] - pix[:n], pix[2 * n :] - pix[:n]
    extent_x = np.sqrt((along_x[:, 0] ** 2 + along_x[:, 1] ** 2).max())
    return float(extent_x), float(np.sqrt((along_y[:, 0] ** 2 + along_y[:, 1] ** 2).max()))


def subgrid(
    footprint_px: tuple[float, float], *, filter: str = "box", max_supersample: int = 8
) -> tuple[int, int]:
    """(s_x, s_y): the sub-samples per texel side :func:`rectify` takes for a grid whose
    largest texel step spans ``footprint_px`` = (along x, along y) pixels: one per
    pixel for the box (at most ``max_supersample``), :data:`AREA_SAMPLES_PER_PIXEL`
    per pixel for the area filter."""
    if filter == "area":
        density, most = AREA_SAMPLES_PER_PIXEL, _MAX_AREA_SAMPLES
    else:
        density, most = 1, max_supersample
    sx, sy = (int(np.clip(np.ceil(density * f), 1, most)) for f in footprint_px)
    return sx, sy


def rectify(
    frame: np.ndarray,
    homography: PlaneHomography,
    *,
    sample_mm: float,
    size: int,
    camera: PinholeCamera | None = None,
    region: Region | None = None,
    extend_texels: int = 0,
    order: int = 1,
    max_supersample: int = 8,
    filter: str = "box",
) -> Normtexture:
    """Rectify ``frame`` onto the N×N texel grid of the sample square (or a region).

    Parameters
    ----------
    frame : (H, W) or (H, W, C) array, C ∈ {1, 3}, integer or float
        Raw frame (not undistorted).
    homography : PlaneHomography
        From :func:`fit_plane_homography`; must be ``valid``.
    sample_mm : float
        Side of the sample square (``holder.sample_mm``); ignored with ``region``.
    size : int
        N, texels per side.
    camera : PinholeCamera, optional
        Lens distortion applied when sampling the raw frame.
    region : Region, optional
        Rectify this square instead of the whole sample square.
    extend_texels : int
        Extra texels sampled past the +x and −y edges (the last columns and
        rows), on the same grid step, for :func:`blend_edges`.
    order : int
        Interpolation order, 1 (bilinear) or 3 (cubic spline).
    max_supersample : int
        Cap on sub-samples per texel and axis (``filter="box"``).
    filter : str
        ``"box"``: the mean of s_x × s_y interpolated samples; ``"area"``: each pixel
        weighted by its share of the texel's footprint (``order`` is not used).

    Returns
    -------
    Normtexture
        ``texture`` is (N + extend, N + extend, C) float32.
    """
    image = _as_frame(frame)
    if not homography.valid:
        raise RegistrationError(
            f"homography is flagged {homography.reason.name}; a flagged frame must not be warped"
        )
    if size < 1 or extend_texels < 0 or max_supersample < 1:
        raise RegistrationError(
            f"size = {size}, extend_texels = {extend_texels}, max_supersample = "
            f"{max_supersample}: need size ≥ 1, extend_texels ≥ 0, max_supersample ≥ 1"
        )
    if order not in (1, 3):
        raise RegistrationError(f"order = {order}: valid are 1 (bilinear) and 3 (cubic)")
    if filter not in FILTERS:
        raise RegistrationError(f"filter = {filter!r}: valid are {list(FILTERS)}")
    side = sample_mm if region is None else region.side_mm
    if not np.isfinite(side) or side <= 0:
        raise RegistrationError(f"sample_mm = {sample_mm}: must be > 0")
    step = side / size
    n_out = size + extend_texels
    center = None if region is None else tuple(float(v) for v in region.center_mm)
    grid = _texel_grid(float(side), size, extend_texels, center)
    H = homography.plane_to_image
    # Without a lens model the sample positions are the homography's alone: footprint,
    # positions and samples come from compiled passes without (n, 2) temporaries.
    pinhole = camera is None or not np.any(camera.dist)
    if pinhole:
        fx, fy = homography_footprint_px(H, grid.reshape(-1, 2), step)
    else:
        fx, fy = _footprint_px(H, grid, step, camera)
    if filter == "area":  # each sample takes the pixel it falls in (nearest, order 0)
        order = 0
    sx, sy = subgrid((fx, fy), filter=filter, max_supersample=max_supersample)
    sub = _sub_offsets(sx, sy, step)

    height, width, channels = image.shape
    if order != 1:  # nearest (the area filter) or cubic, by scipy
        planes = [np.asarray(image[:, :, c], dtype=np.float64) for c in range(channels)]
        if order == 3:
            planes = [ndimage.spline_filter(p, order=3, mode="nearest") for p in planes]
    valid = np.ones((n_out, n_out), bool)
    if order == 1 and pinhole:  # the texels' means rounded to float32 as they are stored
        texture = np.empty((n_out, n_out, channels), np.float32)
        flat = texture.reshape(-1, channels)
        project_box_bilinear(image, H, grid.reshape(-1, 2), sub, flat, valid.reshape(-1))
        if not valid.all():
            texture[~valid] = 0.0
        return Normtexture(texture, valid, (sx, sy))
    texture = np.zeros((n_out, n_out, channels), np.float64)
    rows_per_strip = max(1, _MAX_SAMPLES_PER_STRIP // (n_out * len(sub)))
    for r0 in range(0, n_out, rows_per_strip):
        block = grid[r0 : r0 + rows_per_strip]  # (r, n_out, 2)
        pts = (block[:, :, None, :] + sub[None, None, :, :]).reshape(-1, 2)
        pix = _to_pixels(H, pts, camera)
        inside = (
            (pix[:, 0] >= -0.5) & (pix[:, 0] <= width - 0.5)
            & (pix[:, 1] >= -0.5) & (pix[:, 1] <= height - 0.5)
        )  # fmt: skip
        shape = (*block.shape[:2], len(sub))
        valid[r0 : r0 + len(block)] = inside.reshape(shape).all(axis=2)
        strip = texture[r0 : r0 + len(block)]
        if order == 1:
            box_bilinear(image, pix, len(sub), strip.reshape(-1, channels))
            continue
        coords = np.stack([pix[:, 1], pix[:, 0]])
        for c, plane in enumerate(planes):
            values = ndimage.map_coordinates(
                plane, coords, order=order, mode="nearest", prefilter=False
            )
            strip[:, :, c] = values.reshape(shape).mean(axis=2)
    texture[~valid] = 0.0
    return Normtexture(texture.astype(np.float32), valid, (sx, sy))


@functools.lru_cache(maxsize=32)
def _texel_grid(
    side_mm: float, size: int, extend_texels: int, center_mm: tuple[float, float] | None
) -> np.ndarray:
    """(n, n, 2) read-only texel centres, n = ``size + extend_texels``: the shared grid of a
    square of ``side_mm`` (centred on ``center_mm``), extended past the last column (+x)
    and row (−y). Kept: every frame of a session asks for the same one."""
    step = side_mm / size
    n_out = size + extend_texels
    grid = texel_centers_mm(step * n_out, n_out) + (step * extend_texels / 2) * np.array(
        [1.0, -1.0]
    )
    if center_mm is not None:
        grid = grid + np.asarray(center_mm, dtype=np.float64)
    grid.setflags(write=False)
    return grid


@functools.lru_cache(maxsize=64)
def _sub_offsets(sx: int, sy: int, step_mm: float) -> np.ndarray:
    """(sx · sy, 2) read-only offsets from a texel's centre of its sub-samples, x fastest."""
    offsets_x = ((np.arange(sx) + 0.5) / sx - 0.5) * step_mm
    offsets_y = ((np.arange(sy) + 0.5) / sy - 0.5) * step_mm
    sub = np.column_stack([np.tile(offsets_x, sy), np.repeat(offsets_y, sx)])
    sub.setflags(write=False)
    return sub


def blend_edges(texture: np.ndarray, *, blend: int) -> np.ndarray:
    """Make a tileable texture by linear edge blending (seed 000 §3.2).

    ``texture`` is (N + b, N + b, C), rectified with ``extend_texels = b``. The
    extra b columns past the +x edge are cross-faded into the first b columns
    (and the extra rows past −y into the first rows), so texel N − 1 continues
    smoothly into texel 0 when the N×N result is tiled.

    Returns
    -------
    (N, N, C) float32
    """
    t = np.asarray(texture, dtype=np.float64)
    if t.ndim != 3 or t.shape[0] != t.shape[1]:
        raise RegistrationError(f"texture: expected (N + b, N + b, C), got shape {t.shape}")
    n = t.shape[0] - blend
    if blend < 0 or n < max(blend, 1):
        raise RegistrationError(
            f"blend = {blend} for a texture of {t.shape[0]} texels: need 0 ≤ blend ≤ "
            f"{t.shape[0] // 2} (the extension may be at most the tile size)"
        )
    ramp = (np.arange(blend) + 0.5) / max(blend, 1)  # weight of the tile's own texels
    cols = t[:, :n].copy()
    cols[:, :blend] = ramp[None, :, None] * t[:, :blend] + (1 - ramp)[None, :, None] * t[:, n:]
    out = cols[:n].copy()
    out[:blend] = ramp[:, None, None] * cols[:blend] + (1 - ramp)[:, None, None] * cols[n:]
    return out.astype(np.float32)
