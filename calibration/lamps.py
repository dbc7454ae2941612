"""Lamp calibration with a mirror sphere and a diffuse white target.

A chrome sphere of known radius shows each lamp as a highlight. The camera ray
through the highlight hits the sphere where the surface normal halves the
angle between the view and the lamp, so reflecting the view ray there points
at the lamp: a direction for a distant lamp. For a near lamp, the reflected
rays from two or more sphere positions meet at the lamp (least squares).
A diffuse white target under each lamp gives the lamps' relative intensities
and the fall-off (flat field) each casts on the sample plane.

From frames: :func:`locate_sphere` finds the ball's centre from its outline
(:func:`sphere_silhouette`) — a dark ball against the lit plate or a bright
one against a dark background — or takes a mask of it;
:func:`sphere_ray` turns one :class:`SphereShot` into the reflected ray of its
highlight, and :func:`lamp_direction` / :func:`lamp_position` combine the rays
of one lamp from all cameras, turntable angles and frames. The centre comes
from the same view as the highlight, so a small error in the camera's pose
moves both together and hardly turns the reflected ray. A distant setup
without a calibrated camera (a ball photographed from afar) uses an
``OrthographicCamera``: its rays are parallel and the lamp directions come
out in its frame. :func:`lamp_intensities` divides white-target images by
each lamp's geometry (E = I·cosθ/r²).

All geometry is in one frame (the world or sample frame of the camera model),
lengths in mm.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from calibration._sphere import (
    Camera,
    LampCalibrationError,
    SphereOutline,
    inside_mask,
    locate_sphere,
    sphere_center_from_silhouette,
    sphere_silhouette,
    towards_camera,
)
from calibration._white import FlatField, flat_fields, lamp_intensities
from rig.camera import PinholeCamera
from rig.targets import MirrorSphere

__all__ = [
    "FlatField",
    "Highlight",
    "LampCalibrationError",
    "LampDirection",
    "LampPosition",
    "LampRay",
    "SphereOutline",
    "SphereShot",
    "find_highlight",
    "flat_fields",
    "lamp_direction",
    "lamp_intensities",
    "lamp_position",
    "locate_sphere",
    "reflected_ray",
    "sphere_center_from_silhouette",
    "sphere_ray",
    "sphere_silhouette",
    "triangulate_lamp",
]


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
    the rays are nearly parallel — spread the sphere positions further);
    ``clipped`` how many of the rays came from clipped highlights.
    """

    position_mm: np.ndarray
    rms_distance_mm: float
    condition: float
    rays: int
    clipped: int = 0


@dataclass(frozen=True)
class SphereShot:
    """One camera's view of the mirror sphere under one lamp.

    camera : the camera's model in the world frame (turntable at 0°), where
        the sphere stands at ``MirrorSphere.centre_mm(turntable_deg)``; an
        ``OrthographicCamera`` for a distant setup
    image : (H, W[, C]) the frame the highlight is found in; expose it so that
        the highlight does not clip (a clipped one still works, less precisely)
    silhouette : a longer exposure of the same view in which the ball stands
        out from its background, or None to find the outline in ``image``
    mask : (H, W) bool or uint8 0/255, the ball's pixels: where to look for
        the outline when the sphere's nominal place is not known
    sphere : the sphere already located (once per view for all its lamps, or
        ``SphereOutline.given`` a known centre); None to locate it here
    lamp, camera_id, frame : names for messages
    """

    lamp: str
    camera_id: str
    camera: Camera
    image: np.ndarray
    turntable_deg: float = 0.0
    silhouette: np.ndarray | None = None
    frame: str = ""
    mask: np.ndarray | None = None
    sphere: SphereOutline | None = None

    @property
    def name(self) -> str:
        frame = f", frame {self.frame}" if self.frame else ""
        return (
            f"lamp {self.lamp}, camera {self.camera_id}{frame} (turntable {self.turntable_deg:g}°)"
        )


@dataclass(frozen=True)
class LampRay:
    """A highlight's reflected ray: from ``point_mm`` (3,) on the sphere along
    ``direction`` (3,) unit, towards the lamp.

    ``incidence_deg`` is the angle between the camera ray and the sphere's
    normal at the highlight (half the angle between camera and lamp). Towards
    the rim a pixel spans more of the sphere, so the ray's direction error
    grows as 1 / cos(incidence): :attr:`weight` is cos², its inverse variance.
    """

    point_mm: np.ndarray
    direction: np.ndarray
    highlight: Highlight
    sphere: SphereOutline
    incidence_deg: float

    @property
    def weight(self) -> float:
        return float(np.cos(np.deg2rad(self.incidence_deg)) ** 2)


@dataclass(frozen=True)
class LampDirection:
    """A distant lamp's ``direction`` (3,) unit, towards the lamp.

    ``spread_deg`` is the RMS angle of the rays from it: how far one
    highlight's direction may be off. It is None for a single ray — one
    highlight cannot say how good it is; shoot the lamp from more turntable
    angles, cameras or frames. ``clipped`` how many of the rays came from
    clipped highlights.
    """

    direction: np.ndarray
    spread_deg: float | None
    rays: int
    clipped: int

    @property
    def uncertainty_deg(self) -> float | None:
        """Standard error of ``direction`` (spread / √(rays − 1)); None for one ray."""
        if self.spread_deg is None:
            return None
        return self.spread_deg / np.sqrt(self.rays - 1)


def find_highlight(
    image, sphere_mask, *, saturation_level: float, threshold: float = 0.5
) -> Highlight:
    """The sub-pixel centroid of the brightest blob inside the sphere.

    Parameters
    ----------
    image : (H, W) or (H, W, C) array, any real dtype
    sphere_mask : (H, W) bool, where the sphere is
    saturation_level : the value at which the camera clips
    threshold : pixels above ``threshold`` of the way from the ball's median
        level to the peak belong to the highlight (a ball that reflects a lit
        room is far from black)
    """
    img = np.asarray(image, dtype=np.float64)
    if img.ndim == 3:
        img = img.max(axis=-1)
    mask = np.asarray(sphere_mask, dtype=bool)
    if mask.shape != img.shape:
        raise LampCalibrationError(f"sphere_mask {mask.shape} does not match image {img.shape}")
    if not mask.any():
        raise LampCalibrationError("sphere_mask is empty: no pixel of the sphere to search")
    base = float(np.median(img[mask]))
    inside = np.where(mask, img, base)
    peak = float(inside.max())
    if peak <= base:
        raise LampCalibrationError("no highlight on the sphere: it is evenly dark or lit")
    level = base + threshold * (peak - base)
    labels, _ = ndimage.label(inside > level)
    brightest = labels[np.unravel_index(np.argmax(inside), inside.shape)]
    blob = labels == brightest
    weights = np.where(blob, inside - level, 0.0)
    ys, xs = np.nonzero(blob)
    w = weights[ys, xs]
    if w.sum() <= 0:  # a flat (saturated) blob: plain centroid
        w = np.ones_like(w)
    pixel = np.array([np.sum(xs * w) / w.sum(), np.sum(ys * w) / w.sum()])
    clipped = bool(np.any(img[blob] >= saturation_level))
    return Highlight(pixel, peak, clipped, int(blob.sum()))


def reflected_ray(
    camera: Camera, pixel, center_mm, radius_mm: float
) -> tuple[np.ndarray, np.ndarray]:
    """Where the camera ray through ``pixel`` hits the sphere, and the
    reflected direction there (towards the lamp).

    Returns ``(point (3,), direction (3,) unit)``; raises when the ray misses.
    """
    origin, d = camera.rays(np.asarray(pixel, dtype=np.float64).reshape(1, 2))
    origin, d = np.reshape(origin, (-1, 3))[0], d[0]  # one centre, or one origin per ray
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


def triangulate_lamp(
    points, directions, *, weights=None, max_condition: float = 1e6
) -> LampPosition:
    """Least-squares intersection of rays ``points[i] + t·directions[i]``.

    Minimises the (weighted) summed squared distance to the rays:
    Σ wᵢ (I − dᵢdᵢᵀ)(x − pᵢ) = 0, with ``weights`` (n,) > 0 (default 1).
    Nearly parallel rays make the system ill-conditioned and raise.
    """
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    d = np.asarray(directions, dtype=np.float64).reshape(-1, 3)
    if len(p) < 2 or len(p) != len(d):
        raise LampCalibrationError(f"need ≥ 2 rays with a point and a direction each, got {len(p)}")
    w = np.ones(len(p)) if weights is None else np.asarray(weights, dtype=np.float64).reshape(-1)
    if w.shape != (len(p),) or not np.all(np.isfinite(w) & (w > 0)):
        raise LampCalibrationError(f"weights: expected {len(p)} finite values > 0, got {w}")
    d = d / np.linalg.norm(d, axis=1, keepdims=True)
    projectors = np.eye(3)[None] - d[:, :, None] * d[:, None, :]
    A = np.einsum("n,nij->ij", w, projectors)
    b = np.einsum("n,nij,nj->i", w, projectors, p)
    condition = float(np.linalg.cond(A))
    if not np.isfinite(condition) or condition > max_condition:
        raise LampCalibrationError(
            f"the reflected rays are nearly parallel (condition {condition:.3g}); "
            "move the sphere further between the positions"
        )
    x = np.linalg.solve(A, b)
    dist = np.linalg.norm(np.einsum("nij,nj->ni", projectors, x - p), axis=1)
    return LampPosition(x, float(np.sqrt(np.mean(dist**2))), condition, len(p))


def sphere_ray(shot: SphereShot, sphere: MirrorSphere, *, saturation_level: float) -> LampRay:
    """The reflected ray of the lamp's highlight in one shot.

    The sphere is ``shot.sphere`` if given, else located in ``shot.silhouette``
    (or ``shot.image``): around ``shot.mask`` if given, else around its nominal
    place ``sphere.centre_mm(shot.turntable_deg)`` for a ``PinholeCamera``, or
    wherever the ball is in the image for an ``OrthographicCamera`` (whose fit
    gives the radius: ``sphere.radius_mm`` serves the pinhole fit only). The
    highlight is the brightest blob inside the outline (2 px in from it), and
    must stand 10 σ of the ball's pixel noise above the ball's median level.
    Errors name the lamp, camera, frame and turntable angle of the shot.
    """
    camera = shot.camera
    pinhole = isinstance(camera, PinholeCamera)
    try:
        outline = shot.sphere or locate_sphere(
            camera,
            shot.image if shot.silhouette is None else shot.silhouette,
            radius_mm=sphere.radius_mm,
            guess_mm=sphere.centre_mm(shot.turntable_deg) if pinhole else None,
            mask=shot.mask,
            centre_z_mm=sphere.radius_mm if pinhole else None,
        )
        image = _channel_max(shot.image)
        inside = inside_mask(camera, outline.centre_mm, outline.radius_mm, image.shape)
        highlight = find_highlight(image, inside, saturation_level=saturation_level)
        background = np.median(image[inside])
        # Noise from neighbour differences: a ball reflecting a lit room varies
        # smoothly across, far more than its pixels do from one to the next.
        pairs = inside[:, 1:] & inside[:, :-1]
        noise = 1.4826 * np.median(np.abs(np.diff(image, axis=1)[pairs])) / np.sqrt(2)
        if highlight.peak - background < max(10 * noise, 0.01 * saturation_level):
            raise LampCalibrationError(
                f"no highlight on the sphere: its brightest point ({highlight.peak:.4g}) is "
                f"within noise of the ball's level ({background:.4g} ± {noise:.2g}); "
                "is the lamp lit and in view of the ball?"
            )
        point, direction = reflected_ray(
            camera, highlight.pixel, outline.centre_mm, outline.radius_mm
        )
    except LampCalibrationError as err:
        raise LampCalibrationError(f"{shot.name}: {err}") from err
    normal = (point - outline.centre_mm) / outline.radius_mm
    incidence = np.degrees(np.arccos(np.clip(normal @ towards_camera(camera, point), -1, 1)))
    return LampRay(point, direction, highlight, outline, float(incidence))


def lamp_direction(rays: Sequence[LampRay]) -> LampDirection:
    """A distant lamp's direction: the weighted mean of its rays' directions.

    A distant lamp's rays are parallel wherever they leave the sphere, so rays
    from every camera and turntable angle (in one frame) average, each by its
    :attr:`LampRay.weight`. Their spread says how far one may be off; a
    single ray gives none (``spread_deg`` None).
    """
    if not rays:
        raise LampCalibrationError("lamp_direction: no rays (no highlight was found)")
    d = np.array([ray.direction for ray in rays], dtype=np.float64)
    w = np.array([ray.weight for ray in rays])
    mean = w @ d
    if np.linalg.norm(mean) < 0.5 * w.sum():
        raise LampCalibrationError(
            f"lamp_direction: the {len(d)} rays disagree by more than 60° on average; "
            "are they from one distant lamp and in one frame?"
        )
    mean /= np.linalg.norm(mean)
    angles = np.arccos(np.clip(d @ mean, -1.0, 1.0))
    return LampDirection(
        mean,
        float(np.degrees(np.sqrt(np.mean(angles**2)))) if len(d) > 1 else None,
        len(d),
        sum(ray.highlight.clipped for ray in rays),
    )


def lamp_position(rays: Sequence[LampRay], *, max_condition: float = 1e4) -> LampPosition:
    """A near lamp's position: where its reflected rays meet (:func:`triangulate_lamp`,
    each ray weighted by its :attr:`LampRay.weight`).

    The rays must come from the sphere at two or more places (turntable
    angles): their spread is the baseline, so the further the sphere stands
    from the axis the better. A distant lamp's rays are parallel: rays within
    about a degree of parallel (``max_condition``) raise, as do rays that meet
    behind the sphere.
    """
    if len(rays) < 2:
        raise LampCalibrationError(f"lamp_position: need ≥ 2 rays, got {len(rays)}")
    points = np.array([ray.point_mm for ray in rays])
    dirs = np.array([ray.direction for ray in rays])
    weights = np.array([max(ray.weight, 1e-6) for ray in rays])
    found = triangulate_lamp(points, dirs, weights=weights, max_condition=max_condition)
    ahead = np.einsum("ij,ij->i", found.position_mm - points, dirs)
    if np.any(ahead <= 0):
        raise LampCalibrationError(
            f"lamp_position: the rays meet behind the sphere ({int(np.sum(ahead <= 0))} of "
            f"{len(rays)}), so they are not from one near lamp"
        )
    clipped = sum(ray.highlight.clipped for ray in rays)
    return LampPosition(found.position_mm, found.rms_distance_mm, found.condition, found.rays,
                        clipped)  # fmt: skip


def _channel_max(image) -> np.ndarray:
    img = np.asarray(image, dtype=np.float64)
    return img.max(axis=-1) if img.ndim == 3 else img
