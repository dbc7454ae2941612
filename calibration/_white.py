"""Lamp intensities and fall-off from a diffuse white target (part of
:mod:`calibration.lamps`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calibration._sphere import LampCalibrationError
from rig.camera import PinholeCamera


@dataclass(frozen=True)
class FlatField:
    """Relative lamp intensities and each lamp's fall-off on the target.

    ``intensity`` (L,) float64, the brightest lamp = 1; ``falloff`` (L, H, W)
    float32, each lamp's image divided by its value at the target centre.
    """

    intensity: np.ndarray
    falloff: np.ndarray


def flat_fields(images, *, center_fraction: float = 0.1) -> FlatField:
    """Relative intensities and fall-off maps from a white target, one image per lamp.

    Parameters
    ----------
    images : (L, H, W) or (L, H, W, C) linear values (use a linearised image)
    center_fraction : side of the central square, as a fraction of the image,
        whose median is a lamp's value at the target centre
    """
    stack = np.asarray(images, dtype=np.float64)
    if stack.ndim == 4:
        stack = stack.mean(axis=-1)
    if stack.ndim != 3 or len(stack) < 1:
        raise LampCalibrationError(f"images: expected (L, H, W[, C]), got {np.shape(images)}")
    if not np.all(np.isfinite(stack)):
        raise LampCalibrationError("images contain NaN or inf")
    _, H, W = stack.shape
    hh, hw = max(1, int(H * center_fraction / 2)), max(1, int(W * center_fraction / 2))
    center = stack[:, H // 2 - hh : H // 2 + hh + 1, W // 2 - hw : W // 2 + hw + 1]
    level = np.median(center.reshape(len(stack), -1), axis=1)
    dark = np.flatnonzero(level <= 0)
    if len(dark):
        raise LampCalibrationError(
            f"lamp image(s) {dark.tolist()} are dark at the target centre: a lamp that does "
            "not light, or the target is not under it"
        )
    return FlatField(level / level.max(), (stack / level[:, None, None]).astype(np.float32))


def lamp_intensities(
    camera: PinholeCamera,
    images,
    *,
    positions_mm=None,
    directions=None,
    saturation_level: float,
    target_xy_mm=(0.0, 0.0),
    target_z_mm: float = 0.0,
    patch_mm: float = 20.0,
) -> np.ndarray:
    """Relative lamp intensities from a white target, one image per lamp.

    Each pixel of the target within ``patch_mm``/2 of its centre is divided
    by its lamp's geometry there — ``cosθ / r²`` for a near lamp at
    ``positions_mm``, ``cosθ`` for a distant lamp along ``directions`` — and
    the quotients averaged. The same pixels serve every lamp, so the
    vignetting and the target's reflectance cancel between lamps.

    Parameters
    ----------
    images : (L, H, W) or (L, H, W, C) linear values of one camera
    positions_mm, directions : (L, 3); give exactly one (near lamps give
        radiant intensities, distant ones normal irradiances: not comparable)
    target_z_mm : height of the target's surface (0: the reference plane)

    Returns
    -------
    (L,) float64, the brightest lamp = 1
    """
    stack = np.asarray(images, dtype=np.float64)
    if stack.ndim == 4:
        stack = stack.mean(axis=-1)
    if stack.ndim != 3 or stack.shape[1:] != (camera.height, camera.width):
        raise LampCalibrationError(
            f"images: expected (L, {camera.height}, {camera.width}[, C]) for this camera, "
            f"got {np.shape(images)}"
        )
    if (positions_mm is None) == (directions is None):
        raise LampCalibrationError("lamp_intensities: give positions_mm or directions, not both")
    lamps = np.asarray(positions_mm if directions is None else directions, dtype=np.float64)
    if lamps.shape != (len(stack), 3) or not np.all(np.isfinite(lamps)):
        raise LampCalibrationError(
            f"{'directions' if positions_mm is None else 'positions_mm'}: expected finite "
            f"({len(stack)}, 3), one per image, got {lamps.shape}"
        )
    rows, cols, surface = _target_pixels(camera, target_xy_mm, target_z_mm, patch_mm)
    values = stack[:, rows, cols]
    clipped = np.flatnonzero(np.any(values >= saturation_level, axis=1))
    dark = np.flatnonzero(values.mean(axis=1) <= 0)
    problems = []
    if len(clipped):
        problems.append(f"lamp image(s) {clipped.tolist()} clip on the target: expose shorter")
    if len(dark):
        problems.append(
            f"lamp image(s) {dark.tolist()} are dark on the target: a lamp that does not "
            "light, or expose longer"
        )
    if problems:
        raise LampCalibrationError("; ".join(problems))
    if directions is None:
        to_lamp = lamps[:, None, :] - surface[None]
        r2 = np.einsum("lnk,lnk->ln", to_lamp, to_lamp)
        geometry = to_lamp[..., 2] / np.sqrt(r2) / r2
    else:
        unit = lamps / np.linalg.norm(lamps, axis=1, keepdims=True)
        geometry = np.broadcast_to(unit[:, 2:3], values.shape)
    below = np.flatnonzero(np.any(geometry <= 0, axis=1))
    if len(below):
        raise LampCalibrationError(f"lamp(s) {below.tolist()} are not above the target")
    level = np.mean(values / geometry, axis=1)
    return level / level.max()


def _target_pixels(camera: PinholeCamera, target_xy_mm, target_z_mm: float, patch_mm: float):
    """Rows, columns and surface points (n, 3) of the pixels seeing the target patch."""
    xy = np.asarray(target_xy_mm, dtype=np.float64)
    phi = np.linspace(0, 2 * np.pi, 16, endpoint=False)
    rim = np.column_stack([xy[0] + patch_mm / 2 * np.cos(phi), xy[1] + patch_mm / 2 * np.sin(phi),
                           np.full(16, target_z_mm)])  # fmt: skip
    corners, in_front = camera.project(rim)
    x0, y0 = np.clip(np.floor(corners.min(axis=0)).astype(int), 0, None)
    x1 = min(int(np.ceil(corners[:, 0].max())), camera.width - 1)
    y1 = min(int(np.ceil(corners[:, 1].max())), camera.height - 1)
    if not np.all(in_front) or x1 < x0 or y1 < y0:
        raise LampCalibrationError(f"the target patch at {xy.tolist()} mm is not in view")
    rows, cols = np.mgrid[y0 : y1 + 1, x0 : x1 + 1]
    rows, cols = rows.ravel(), cols.ravel()
    origin, d = camera.rays(np.column_stack([cols, rows]))
    grazing = np.abs(d[:, 2]) < 1e-12
    t = np.where(grazing, -1.0, (target_z_mm - origin[2]) / np.where(grazing, 1.0, d[:, 2]))
    surface = origin + t[:, None] * d
    inside = (t > 0) & (np.linalg.norm(surface[:, :2] - xy, axis=1) <= patch_mm / 2)
    if inside.sum() < 9:
        raise LampCalibrationError(
            f"only {int(inside.sum())} pixels see the {patch_mm:g} mm target patch; enlarge it"
        )
    return rows[inside], cols[inside], surface[inside]
