"""Lamp calibration with a mirror sphere and a diffuse white target.

A chrome sphere of known radius shows each lamp as a highlight. The camera ray
through the highlight hits the sphere where the surface normal halves the
angle between the view and the lamp, so reflecting the view ray there points
at the lamp: a direction for a distant lamp. For a near lamp, the reflected
rays from two or more sphere positions meet at the lamp (least squares).
A diffuse white target under each lamp gives the lamps' relative intensities
and the fall-off (flat field) each casts on the sample plane.

All geometry is in one frame (the world or sample frame of the camera model),
lengths in mm.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from rig.camera import PinholeCamera
from rig.errors import RigError

__all__ = [
    "FlatField",
    "Highlight",
    "LampCalibrationError",
    "LampPosition",
    "find_highlight",
    "flat_fields",
    "reflected_ray",
    "sphere_center_from_silhouette",
    "triangulate_lamp",
]


class LampCalibrationError(RigError):
    """The images cannot give a trustworthy lamp direction or position."""


@dataclass(frozen=True)
class Highlight:
    """The sub-pixel centre of a specular highlight.

    ``clipped`` is True when the highlight's core is saturated: its centroid
    is then the centre of the clipped blob, still usable but less precise.
    """

    pixel: np.ndarray  # (2,) float64, x, y
    peak: float
    clipped: bool
    area_px: int


@dataclass(frozen=True)
class LampPosition:
    """A near lamp's position and how well the rays agreed.

    ``rms_distance_mm`` is the RMS distance of the rays from the point;
    ``condition`` the condition number of the normal equations (large when
    the rays are nearly parallel — spread the sphere positions further).
    """

    position_mm: np.ndarray
    rms_distance_mm: float
    condition: float
    rays: int


@dataclass(frozen=True)
class FlatField:
    """Relative lamp intensities and each lamp's fall-off on the target.

    ``intensity`` (L,) float64, the brightest lamp = 1; ``falloff`` (L, H, W)
    float32, each lamp's image divided by its value at the target centre.
    """

    intensity: np.ndarray
    falloff: np.ndarray


def sphere_center_from_silhouette(
    camera: PinholeCamera, boundary_px, radius_mm: float
) -> np.ndarray:
    """The sphere centre from pixels on its silhouette.

    The rays tangent to a sphere form a cone around the ray to its centre with
    half-angle β, sin β = r / D. So every boundary ray d satisfies d·a = cos β
    for the unit axis a: a linear least-squares problem in a / cos β.

    Parameters
    ----------
    boundary_px : (n, 2) float
        Pixels on the silhouette, n ≥ 3 spread around it.
    """
    pts = np.asarray(boundary_px, dtype=np.float64).reshape(-1, 2)
    if len(pts) < 3:
        raise LampCalibrationError(f"need ≥ 3 silhouette pixels, got {len(pts)}")
    origin, d = camera.rays(pts)
    # d · x = 1 with x = a / cos β
    x, *_ = np.linalg.lstsq(d, np.ones(len(d)), rcond=None)
    cos_beta = 1.0 / np.linalg.norm(x)
    if not 0 < cos_beta < 1:
        raise LampCalibrationError("the silhouette pixels do not outline a sphere")
    axis = x * cos_beta
    sin_beta = np.sqrt(1 - cos_beta**2)
    return origin + axis * radius_mm / sin_beta


def find_highlight(
    image, sphere_mask, *, saturation_level: float, threshold: float = 0.5
) -> Highlight:
    """The sub-pixel centroid of the brightest blob inside the sphere.

    Parameters
    ----------
    image : (H, W) or (H, W, C) array, any real dtype
    sphere_mask : (H, W) bool, where the sphere is
    saturation_level : the value at which the camera clips
    threshold : pixels above ``threshold × peak`` belong to the highlight
    """
    img = np.asarray(image, dtype=np.float64)
    if img.ndim == 3:
        img = img.max(axis=-1)
    mask = np.asarray(sphere_mask, dtype=bool)
    if mask.shape != img.shape:
        raise LampCalibrationError(f"sphere_mask {mask.shape} does not match image {img.shape}")
    inside = np.where(mask, img, 0.0)
    peak = float(inside.max())
    if peak <= 0:
        raise LampCalibrationError("no highlight on the sphere: the image is dark there")
    labels, _ = ndimage.label(inside > threshold * peak)
    brightest = labels[np.unravel_index(np.argmax(inside), inside.shape)]
    blob = labels == brightest
    weights = np.where(blob, inside - threshold * peak, 0.0)
    ys, xs = np.nonzero(blob)
    w = weights[ys, xs]
    if w.sum() <= 0:  # a flat (saturated) blob: plain centroid
        w = np.ones_like(w)
    pixel = np.array([np.sum(xs * w) / w.sum(), np.sum(ys * w) / w.sum()])
    clipped = bool(np.any(img[blob] >= saturation_level))
    return Highlight(pixel, peak, clipped, int(blob.sum()))


def reflected_ray(
    camera: PinholeCamera, pixel, center_mm, radius_mm: float
) -> tuple[np.ndarray, np.ndarray]:
    """Where the camera ray through ``pixel`` hits the sphere, and the
    reflected direction there (towards the lamp).

    Returns ``(point (3,), direction (3,) unit)``; raises when the ray misses.
    """
    origin, d = camera.rays(np.asarray(pixel, dtype=np.float64).reshape(1, 2))
    d = d[0]
    oc = origin - np.asarray(center_mm, dtype=np.float64)
    b = oc @ d
    disc = b * b - (oc @ oc - radius_mm**2)
    if disc < 0:
        raise LampCalibrationError(f"the ray through pixel {pixel} misses the sphere")
    t = -b - np.sqrt(disc)
    point = origin + t * d
    normal = (point - center_mm) / radius_mm
    reflected = d - 2 * (d @ normal) * normal
    return point, reflected / np.linalg.norm(reflected)


def triangulate_lamp(points, directions, *, max_condition: float = 1e6) -> LampPosition:
    """Least-squares intersection of rays ``points[i] + t·directions[i]``.

    Minimises the summed squared distance to the rays: Σ (I − dᵢdᵢᵀ)(x − pᵢ) = 0.
    Nearly parallel rays make the system ill-conditioned and raise.
    """
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    d = np.asarray(directions, dtype=np.float64).reshape(-1, 3)
    if len(p) < 2 or len(p) != len(d):
        raise LampCalibrationError(f"need ≥ 2 rays with a point and a direction each, got {len(p)}")
    d = d / np.linalg.norm(d, axis=1, keepdims=True)
    projectors = np.eye(3)[None] - d[:, :, None] * d[:, None, :]
    A = projectors.sum(axis=0)
    b = np.einsum("nij,nj->i", projectors, p)
    condition = float(np.linalg.cond(A))
    if not np.isfinite(condition) or condition > max_condition:
        raise LampCalibrationError(
            f"the reflected rays are nearly parallel (condition {condition:.3g}); "
            "move the sphere further between the positions"
        )
    x = np.linalg.solve(A, b)
    dist = np.linalg.norm(np.einsum("nij,nj->ni", projectors, x - p), axis=1)
    return LampPosition(x, float(np.sqrt(np.mean(dist**2))), condition, len(p))


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
