"""Lamp calibration with a mirror sphere and a diffuse white target.

A chrome sphere of known radius shows each lamp as a highlight. The camera ray
through the highlight hits the sphere where the surface normal halves the
angle between the view and the lamp, so reflecting the view ray there points
at the lamp: a direction for a distant lamp. For a near lamp, the reflected
rays from two or more sphere positions meet at the lamp (least squares).
A diffuse white target under each lamp gives the lamps' relative intensities
and the fall-off (flat field) each casts on the sample plane.

From frames: :func:`locate_sphere` finds the ball's centre from its outline
against the lit plate (:func:`sphere_silhouette`), :func:`sphere_ray` turns
one :class:`SphereShot` into the reflected ray of its highlight, and
:func:`lamp_direction` / :func:`lamp_position` combine the rays of one lamp
from all cameras and turntable angles. The centre comes from the same view as
the highlight, so a small error in the camera's pose moves both together and
hardly turns the reflected ray. :func:`lamp_intensities` divides white-target
images by each lamp's geometry (E = I·cosθ/r²).

All geometry is in one frame (the world or sample frame of the camera model),
lengths in mm.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np
from scipy import ndimage

from rig.camera import PinholeCamera
from rig.errors import RigError
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

_LEVEL_PX = 3.0  # the levels either side of an outline are read this far from it
_STEP_PX = 0.25  # sampling step along a search line
_MIN_OUTLINE_POINTS = 24
_LOCAL_RUN = 11  # outline points whose median residual shows a biased stretch


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
    the rays are nearly parallel — spread the sphere positions further);
    ``clipped`` how many of the rays came from clipped highlights.
    """

    position_mm: np.ndarray
    rms_distance_mm: float
    condition: float
    rays: int
    clipped: int = 0


@dataclass(frozen=True)
class FlatField:
    """Relative lamp intensities and each lamp's fall-off on the target.

    ``intensity`` (L,) float64, the brightest lamp = 1; ``falloff`` (L, H, W)
    float32, each lamp's image divided by its value at the target centre.
    """

    intensity: np.ndarray
    falloff: np.ndarray


@dataclass(frozen=True)
class SphereOutline:
    """The mirror sphere found in one image.

    ``centre_mm`` (3,) float64 in the camera model's frame; ``boundary_px``
    (n, 2) the outline points the fit kept; ``rms_px`` their RMS distance from
    the fitted outline; ``coverage_deg`` how much of the outline they span (less
    than 360 where the ball stands against something as dark as itself: the
    room behind it, its own shadow); ``rejected`` the points left out as outliers.
    """

    centre_mm: np.ndarray
    boundary_px: np.ndarray
    rms_px: float
    coverage_deg: float
    rejected: int


@dataclass(frozen=True)
class SphereShot:
    """One camera's view of the mirror sphere under one lamp.

    camera : the camera's model in the world frame (turntable at 0°), where
        the sphere stands at ``MirrorSphere.centre_mm(turntable_deg)``
    image : (H, W[, C]) the frame the highlight is found in; expose it so that
        the highlight does not clip (a clipped one still works, less precisely)
    silhouette : a longer exposure of the same view in which the plate around
        the ball is well lit, or None to find the outline in ``image``
    lamp, camera_id, frame : names for messages
    """

    lamp: str
    camera_id: str
    camera: PinholeCamera
    image: np.ndarray
    turntable_deg: float = 0.0
    silhouette: np.ndarray | None = None
    frame: str = ""

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

    ``spread_deg`` is the RMS angle of the rays from it (0 for one ray);
    ``clipped`` how many of the rays came from clipped highlights.
    """

    direction: np.ndarray
    spread_deg: float
    rays: int
    clipped: int


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


def sphere_silhouette(
    image, outline_px, *, search_px: float = 4.0, min_contrast: float = 0.25
) -> np.ndarray:
    """Sub-pixel points on the outline of a dark ball against a brighter background.

    Each expected outline point gives a search line from the outline's centroid
    through it. Along the line the outline is where the profile rises most
    steeply within ± ``search_px`` of the expected point; its sub-pixel place is
    where the profile crosses halfway between the levels 3 px inside and
    outside. A line whose rise is below ``min_contrast`` × the 90th percentile of
    all rises (the background as dark as the ball there), or below 10 × the
    image noise, gives no point.

    Parameters
    ----------
    image : (H, W) or (H, W, C) linear values, any real dtype
    outline_px : (n, 2) float, x, y where the outline is expected (e.g. the
        projection of the sphere at its nominal place), in order around it
    search_px : how far the outline may lie from where it is expected

    Returns
    -------
    (m, 2) float64, x, y of the points found, m ≤ n
    """
    img = _grey(image, "image")
    expected = np.asarray(outline_px, dtype=np.float64).reshape(-1, 2)
    centre = expected.mean(axis=0)
    radius = np.linalg.norm(expected - centre, axis=1)
    if len(expected) < 3 or not np.all(radius > 0) or not search_px > 0:
        raise LampCalibrationError(
            f"sphere_silhouette: need ≥ 3 distinct outline points and search_px > 0, got "
            f"{len(expected)} points and search_px={search_px}"
        )
    toward = (expected - centre) / radius[:, None]
    reach = search_px + _LEVEL_PX
    offsets = np.arange(-reach, reach + _STEP_PX / 2, _STEP_PX)
    r = np.clip(radius[:, None] + offsets[None, :], 0.0, None)
    xs, ys = centre[0] + r * toward[:, :1], centre[1] + r * toward[:, 1:]
    profile = ndimage.map_coordinates(img, [ys.ravel(), xs.ravel()], order=1, mode="nearest")
    profile = profile.reshape(r.shape)
    lag, level = round(1 / _STEP_PX), round(_LEVEL_PX / _STEP_PX)
    rise = np.full(r.shape, -np.inf)
    rise[:, lag:-lag] = profile[:, 2 * lag :] - profile[:, : -2 * lag]
    rise[:, np.abs(offsets) > search_px] = -np.inf
    peak = np.argmax(rise, axis=1)
    rows = np.arange(len(r))
    inner, outer = profile[rows, peak - level], profile[rows, peak + level]
    contrast = outer - inner
    # Pixel-to-pixel differences along the lines are mostly noise (an edge is a
    # few of them): a rise must stand well above it.
    steps = profile[:, lag:] - profile[:, :-lag]
    noise = 1.4826 * np.median(np.abs(steps)) / np.sqrt(2)
    strong = (contrast > 10 * noise) & (contrast >= min_contrast * np.percentile(contrast, 90))
    # The edge's place from the dark area under the profile between the two
    # levels (a step at e leaves e − r₀ of it): unlike a halfway crossing it
    # does not depend on how the pixel grid cuts the edge.
    window = peak[:, None] + np.arange(-level, level + 1)[None, :]
    seg = profile[rows[:, None], window]
    span = np.where(strong, contrast, 1.0)[:, None]
    dark = np.clip((outer[:, None] - seg) / span, 0.0, 1.0)
    area = (dark.sum(axis=1) - 0.5 * (dark[:, 0] + dark[:, -1])) * _STEP_PX
    r_edge = r[rows, peak - level] + area
    found = strong
    points = centre + r_edge[:, None] * toward
    return points[found]


def locate_sphere(
    camera: PinholeCamera,
    image,
    *,
    radius_mm: float,
    guess_mm,
    centre_z_mm: float | None = None,
    lines: int = 360,
    search_px: float | None = None,
    min_contrast: float = 0.25,
    max_rms_px: float = 0.5,
    min_coverage_deg: float = 150.0,
) -> SphereOutline:
    """The sphere's centre from its outline in one image.

    The outline of a sphere at ``guess_mm`` (its nominal place) says where to
    look, ± ``search_px`` (default a quarter of its radius in pixels); a
    second pass looks again around the outline of the first fit. Outline
    points far from the fitted outline (a highlight at the rim, an edge of the
    plate next to the ball) are rejected, 3 σ (MAD) at a time.

    The outline fixes the direction to the centre far better than its
    distance (from the outline's size: ~0.01 px of radius is 0.1–0.4 mm at
    the rig's distances, enough to bias a near lamp's range by ~1 %). With
    ``centre_z_mm`` (a sphere resting on a known plane, e.g. ``radius_mm`` above
    the reference plane in the world frame) the centre is where that direction
    meets the height ``centre_z_mm`` instead.

    Raises ``LampCalibrationError`` when fewer than 24 points are found, when
    they span less than ``min_coverage_deg`` of the outline, or when they do
    not fit a sphere of ``radius_mm`` to ``max_rms_px``.
    """
    expected = _outline_px(camera, np.asarray(guess_mm, dtype=np.float64), radius_mm, lines)
    if search_px is None:
        radius_px = np.mean(np.linalg.norm(expected - expected.mean(axis=0), axis=1))
        search_px = max(4.0, float(radius_px) / 4)
    for search in (search_px, 2.0):
        points = sphere_silhouette(image, expected, search_px=search, min_contrast=min_contrast)
        if len(points) < _MIN_OUTLINE_POINTS:
            x, y = expected.mean(axis=0)
            raise LampCalibrationError(
                f"sphere not found: only {len(points)} of {lines} search lines crossed a "
                f"dark-to-bright edge near where its outline should be (around pixel "
                f"({x:.0f}, {y:.0f}) ± {search:.1f} px); is the ball there and the plate lit?"
            )
        centre, keep, residual = _fit_outline(camera, points, radius_mm)
        expected = _outline_px(camera, centre, radius_mm, lines)
    kept = points[keep]
    rms = float(np.sqrt(np.mean(residual[keep] ** 2)))
    middle = expected.mean(axis=0)
    angles = np.sort(np.arctan2(kept[:, 1] - middle[1], kept[:, 0] - middle[0]))
    gaps = np.diff(np.concatenate([angles, angles[:1] + 2 * np.pi]))
    coverage = float(np.degrees(2 * np.pi - gaps.max()))
    if coverage < min_coverage_deg:
        raise LampCalibrationError(
            f"sphere outline too short: it shows against the lit background over "
            f"{coverage:.0f}° only (need ≥ {min_coverage_deg:g}°); light the plate around the ball"
        )
    if rms > max_rms_px:
        raise LampCalibrationError(
            f"the outline found does not fit a sphere of radius {radius_mm:g} mm: RMS "
            f"{rms:.2f} px > {max_rms_px:g} px; check the radius and that the ball is in view"
        )
    if centre_z_mm is not None:
        axis = (centre - camera.center) / np.linalg.norm(centre - camera.center)
        if abs(axis[2]) < 0.1:
            raise LampCalibrationError(
                f"the camera looks at the sphere within {np.degrees(np.arcsin(abs(axis[2]))):.1f}° "
                "of horizontal: its height cannot place it; leave centre_z_mm out"
            )
        centre = camera.center + axis * (centre_z_mm - camera.center[2]) / axis[2]
    return SphereOutline(centre, kept, rms, coverage, int((~keep).sum()))


def sphere_ray(shot: SphereShot, sphere: MirrorSphere, *, saturation_level: float) -> LampRay:
    """The reflected ray of the lamp's highlight in one shot.

    The sphere's outline (in ``shot.silhouette`` if given, else ``shot.image``)
    gives its centre; the highlight is the brightest blob inside the outline
    (2 px in from it), and must stand 10 σ of the ball's own noise above it.
    Errors name the lamp, camera, frame and turntable angle of the shot.
    """
    try:
        outline = locate_sphere(
            shot.camera,
            shot.image if shot.silhouette is None else shot.silhouette,
            radius_mm=sphere.radius_mm,
            guess_mm=sphere.centre_mm(shot.turntable_deg),
            centre_z_mm=sphere.radius_mm,
        )
        image = _channel_max(shot.image)
        inside = _inside_mask(shot.camera, outline.centre_mm, sphere.radius_mm, image.shape)
        highlight = find_highlight(image, inside, saturation_level=saturation_level)
        background = np.median(image[inside])
        noise = 1.4826 * np.median(np.abs(image[inside] - background))
        if highlight.peak - background < max(10 * noise, 0.01 * saturation_level):
            raise LampCalibrationError(
                f"no highlight on the sphere: its brightest point ({highlight.peak:.4g}) is "
                f"within noise of the ball's level ({background:.4g} ± {noise:.2g}); "
                "is the lamp lit and in view of the ball?"
            )
        point, direction = reflected_ray(
            shot.camera, highlight.pixel, outline.centre_mm, sphere.radius_mm
        )
    except LampCalibrationError as err:
        raise LampCalibrationError(f"{shot.name}: {err}") from err
    normal = (point - outline.centre_mm) / sphere.radius_mm
    view = shot.camera.center - point
    incidence = np.degrees(np.arccos(np.clip(normal @ view / np.linalg.norm(view), -1, 1)))
    return LampRay(point, direction, highlight, outline, float(incidence))


def lamp_direction(rays: Sequence[LampRay]) -> LampDirection:
    """A distant lamp's direction: the weighted mean of its rays' directions.

    A distant lamp's rays are parallel wherever they leave the sphere, so rays
    from every camera and turntable angle (in one frame) average, each by its
    :attr:`LampRay.weight`.
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
        float(np.degrees(np.sqrt(np.mean(angles**2)))),
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


def _grey(image, name: str) -> np.ndarray:
    img = np.asarray(image, dtype=np.float64)
    if img.ndim == 3:
        img = img.mean(axis=-1)
    if img.ndim != 2 or not np.all(np.isfinite(img)):
        raise LampCalibrationError(f"{name}: expected finite (H, W[, C]), got {np.shape(image)}")
    return img


def _channel_max(image) -> np.ndarray:
    img = np.asarray(image, dtype=np.float64)
    return img.max(axis=-1) if img.ndim == 3 else img


def _outline_px(camera: PinholeCamera, centre_mm, radius_mm: float, n: int) -> np.ndarray:
    """(n, 2) pixels of a sphere's outline: the projected circle of tangency."""
    to_centre = np.asarray(centre_mm, dtype=np.float64) - camera.center
    dist = np.linalg.norm(to_centre)
    if not dist > radius_mm:
        raise LampCalibrationError(f"the camera is inside the sphere at {centre_mm}")
    axis = to_centre / dist
    u = np.cross(axis, [0.0, 0.0, 1.0] if abs(axis[2]) < 0.9 else [1.0, 0.0, 0.0])
    u /= np.linalg.norm(u)
    w = np.cross(axis, u)
    sin_b = radius_mm / dist
    cos_b = np.sqrt(1 - sin_b**2)
    phi = np.linspace(0, 2 * np.pi, n, endpoint=False)
    rays = cos_b * axis + sin_b * (np.cos(phi)[:, None] * u + np.sin(phi)[:, None] * w)
    pixels, in_front = camera.project(camera.center + rays * dist * cos_b)
    if not np.all(in_front):
        raise LampCalibrationError("the sphere is not in front of the camera")
    return pixels


def _fit_outline(camera: PinholeCamera, points: np.ndarray, radius_mm: float):
    """Centre, kept-mask and residuals (px) of a robust fit to outline points.

    A consensus start (the triple of points a third of the outline apart that
    most points agree with, to 0.5 px) keeps arcs of false edges — a highlight
    near the rim, a marker next to the ball — from pulling the fit; then the
    least-squares fit is repeated without points beyond 3 σ (MAD).
    """
    origin, d = camera.rays(points)
    focal = float(np.mean(np.diag(camera.K)[:2]))
    n = len(points)
    triples = (np.arange(n)[:, None] + np.array([0, n // 3, (2 * n) // 3])[None, :]) % n
    basis = d[triples]  # (n, 3, 3): each triple's rays, one per row
    solvable = np.abs(np.linalg.det(basis)) > 1e-12
    axes = np.linalg.solve(basis[solvable], np.ones((int(solvable.sum()), 3, 1)))[..., 0]
    axes = axes[np.linalg.norm(axes, axis=1) > 1]  # a cone: cos β = 1 / |x| < 1
    keep = np.ones(n, dtype=bool)
    if len(axes):
        cos_beta = 1.0 / np.linalg.norm(axes, axis=1)
        axes *= cos_beta[:, None]
        off = np.abs(np.arccos(np.clip(d @ axes.T, -1, 1)) - np.arccos(cos_beta)) * focal
        keep = off[:, np.argmax(np.sum(off < 0.5, axis=0))] < 0.5
    for _ in range(10):
        if keep.sum() < _MIN_OUTLINE_POINTS:
            raise LampCalibrationError(
                f"sphere not found: only {int(keep.sum())} of {n} outline points agree on "
                "one sphere"
            )
        centre = sphere_center_from_silhouette(camera, points[keep], radius_mm)
        to_centre = centre - origin
        dist = np.linalg.norm(to_centre)
        beta = np.arcsin(radius_mm / dist)
        residual = (np.arccos(np.clip(d @ (to_centre / dist), -1, 1)) - beta) * focal
        sigma = 1.4826 * np.median(np.abs(residual[keep]))
        # A dark marker or wall touching the ball moves a run of neighbouring
        # points off the outline by a fraction of a pixel: too little to stand
        # out one by one, but their local median shows it.
        local = ndimage.median_filter(residual, size=_LOCAL_RUN, mode="wrap")
        new = (np.abs(residual) <= max(3 * sigma, 0.05)) & (np.abs(local) <= max(sigma, 0.03))
        if np.array_equal(new, keep):
            break
        keep = new
    return centre, keep, residual


def _inside_mask(camera: PinholeCamera, centre_mm, radius_mm: float, shape, margin_px=2):
    """(H, W) bool, the pixels inside the sphere's outline, ``margin_px`` in from it."""
    outline = _outline_px(camera, centre_mm, radius_mm, 360)
    mask = np.zeros(shape, dtype=np.uint8)
    cv2.fillPoly(mask, [np.round(outline * 16).astype(np.int32)], 1, cv2.LINE_8, shift=4)
    kernel = np.ones((2 * margin_px + 1, 2 * margin_px + 1), dtype=np.uint8)
    return cv2.erode(mask, kernel).astype(bool)


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
