"""The mirror sphere in an image: its outline and centre.

A ball stands out from its background either way round: a dark chrome ball
against the lit plate (the rig's sessions), or a ball reflecting a bright room
against a dark cloth (a distant setup). :func:`sphere_silhouette` finds
sub-pixel outline points along search lines, :func:`locate_sphere` fits the
sphere to them — a cone of tangent rays for a ``PinholeCamera``, a circle of
free radius for an ``OrthographicCamera`` — starting from the sphere's nominal
place, a mask of it, or the ball found in the image.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy import ndimage

from calibration._outline import LampCalibrationError, Polarity, grey, sphere_silhouette
from rig.camera import OrthographicCamera, PinholeCamera

Camera = PinholeCamera | OrthographicCamera

_MIN_OUTLINE_POINTS = 24
_LOCAL_RUN = 11  # outline points whose median residual shows a biased stretch
_MIN_BALL_PX = 50  # a ball found in the image covers at least this many pixels
_MIN_ROUNDNESS = 0.6  # its area over its enclosing circle's


@dataclass(frozen=True)
class SphereOutline:
    """The mirror sphere found in one image.

    ``centre_mm`` (3,) float64 in the camera model's frame; ``radius_mm`` the
    given radius (pinhole) or the fitted one (orthographic: in pixels when the
    camera's ``mm_per_px`` is 1); ``boundary_px`` (n, 2) the outline points
    the fit kept; ``rms_px`` their RMS distance from the fitted outline;
    ``coverage_deg`` how much of the outline they span (less than 360 where the
    ball stands against something as bright or dark as itself; 0 for a sphere
    given, not measured); ``rejected`` the points left out as outliers.
    """

    centre_mm: np.ndarray
    radius_mm: float
    boundary_px: np.ndarray
    rms_px: float
    coverage_deg: float
    rejected: int

    @classmethod
    def given(cls, centre_mm, radius_mm: float) -> SphereOutline:
        """A sphere whose centre is known (measured once for a fixed setup)."""
        centre = np.asarray(centre_mm, dtype=np.float64).reshape(3)
        if not (np.all(np.isfinite(centre)) and radius_mm > 0):
            raise LampCalibrationError(
                f"SphereOutline.given: centre_mm {centre.tolist()} must be finite and "
                f"radius_mm {radius_mm} > 0"
            )
        return cls(centre, float(radius_mm), np.zeros((0, 2)), 0.0, 0.0, 0)


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


def locate_sphere(
    camera: Camera,
    image,
    *,
    radius_mm: float,
    guess_mm=None,
    mask=None,
    polarity: Polarity = "auto",
    centre_z_mm: float | None = None,
    lines: int = 360,
    search_px: float | None = None,
    min_contrast: float = 0.25,
    max_rms_px: float = 0.5,
    min_coverage_deg: float = 150.0,
) -> SphereOutline:
    """The sphere's centre from its outline in one image.

    Where to look comes from, in this order: ``mask`` ((H, W) bool or uint8
    0/255, the ball's pixels: its circle), ``guess_mm`` (the sphere's nominal
    place: its projected outline), or else the ball found in ``image`` (the
    roundest region, dark or bright as ``polarity`` allows, not touching the
    image border). The outline is searched ± ``search_px`` (default a quarter
    of its radius in pixels) around it, then again around the first fit's.
    Outline points far from the fitted outline (a highlight at the rim, an
    edge of the plate next to the ball) are rejected, 3 σ (MAD) at a time.

    A ``PinholeCamera`` fits the cone of rays tangent to a sphere of
    ``radius_mm``. The outline fixes the direction to the centre far better
    than its distance (from the outline's size: ~0.01 px of radius is
    0.1–0.4 mm at the rig's distances, enough to bias a near lamp's range by
    ~1 %). An ``OrthographicCamera`` fits a circle of free radius: a distant
    lamp's direction needs the sphere's normals only, not its size. With
    ``centre_z_mm`` (a sphere resting on a known plane, e.g. ``radius_mm`` above
    the reference plane in the world frame) the centre is where the ray to it
    meets the height ``centre_z_mm``.

    Raises ``LampCalibrationError`` when fewer than 24 points are found, when
    they span less than ``min_coverage_deg`` of the outline, or when they do
    not fit a sphere to ``max_rms_px``.
    """
    img = grey(image, "image")
    if mask is not None:
        expected = _circle_px(*_ball_in(_as_mask(mask, img.shape), "mask"), lines)
    elif guess_mm is not None:
        expected = _outline_px(camera, np.asarray(guess_mm, dtype=np.float64), radius_mm, lines)
    else:
        expected = _circle_px(*_ball_in_image(img, polarity), lines)
    if search_px is None:
        radius_px = np.mean(np.linalg.norm(expected - expected.mean(axis=0), axis=1))
        search_px = max(4.0, float(radius_px) / 4)
    for search in (search_px, 2.0):
        points = sphere_silhouette(
            img, expected, search_px=search, min_contrast=min_contrast, polarity=polarity
        )
        if len(points) < _MIN_OUTLINE_POINTS:
            x, y = expected.mean(axis=0)
            raise LampCalibrationError(
                f"sphere not found: only {len(points)} of {lines} search lines crossed an "
                f"edge between ball and background near where its outline should be (around "
                f"pixel ({x:.0f}, {y:.0f}) ± {search:.1f} px); is the ball there and does it "
                "stand out from its background?"
            )
        centre, radius, keep, residual = _fit_outline(camera, points, radius_mm)
        expected = _outline_px(camera, centre, radius, lines)
    kept = points[keep]
    rms = float(np.sqrt(np.mean(residual[keep] ** 2)))
    middle = expected.mean(axis=0)
    angles = np.sort(np.arctan2(kept[:, 1] - middle[1], kept[:, 0] - middle[0]))
    gaps = np.diff(np.concatenate([angles, angles[:1] + 2 * np.pi]))
    coverage = float(np.degrees(2 * np.pi - gaps.max()))
    if coverage < min_coverage_deg:
        raise LampCalibrationError(
            f"sphere outline too short: it stands out from its background over "
            f"{coverage:.0f}° only (need ≥ {min_coverage_deg:g}°); light the plate around "
            "the ball (a dark ball) or darken it (a bright one)"
        )
    if rms > max_rms_px:
        raise LampCalibrationError(
            f"the outline found does not fit a sphere (radius {radius:g} mm): RMS "
            f"{rms:.2f} px > {max_rms_px:g} px; check the radius and that the ball is in view"
        )
    if centre_z_mm is not None:
        axis = -towards_camera(camera, centre)
        if abs(axis[2]) < 0.1:
            raise LampCalibrationError(
                f"the camera looks at the sphere within {np.degrees(np.arcsin(abs(axis[2]))):.1f}° "
                "of horizontal: its height cannot place it; leave centre_z_mm out"
            )
        centre = centre + axis * (centre_z_mm - centre[2]) / axis[2]
    return SphereOutline(centre, float(radius), kept, rms, coverage, int((~keep).sum()))


def towards_camera(camera: Camera, point_mm) -> np.ndarray:
    """(3,) unit direction from a world point towards the camera."""
    if isinstance(camera, OrthographicCamera):
        return camera.towards_camera
    view = camera.center - np.asarray(point_mm, dtype=np.float64)
    return view / np.linalg.norm(view)


def inside_mask(camera: Camera, centre_mm, radius_mm: float, shape, margin_px=2) -> np.ndarray:
    """(H, W) bool, the pixels inside the sphere's outline, ``margin_px`` in from it."""
    outline = _outline_px(camera, centre_mm, radius_mm, 360)
    mask = np.zeros(shape, dtype=np.uint8)
    cv2.fillPoly(mask, [np.round(outline * 16).astype(np.int32)], 1, cv2.LINE_8, shift=4)
    kernel = np.ones((2 * margin_px + 1, 2 * margin_px + 1), dtype=np.uint8)
    return cv2.erode(mask, kernel).astype(bool)


def _as_mask(mask, shape) -> np.ndarray:
    m = np.asarray(mask)
    if m.shape != shape:
        raise LampCalibrationError(f"mask: expected the image's shape {shape}, got {m.shape}")
    return m > (m.max() / 2 if m.dtype.kind in "ui" and m.max() > 1 else 0)


def _ball_in(region: np.ndarray, name: str) -> tuple[np.ndarray, float]:
    """Centre (x, y) and radius (px) of the largest filled component of ``region``."""
    labels, count = ndimage.label(ndimage.binary_fill_holes(region))
    if count == 0:
        raise LampCalibrationError(f"{name}: no ball in it (empty)")
    sizes = ndimage.sum_labels(np.ones_like(labels), labels, np.arange(1, count + 1))
    ys, xs = np.nonzero(labels == 1 + int(np.argmax(sizes)))
    return np.array([xs.mean(), ys.mean()]), float(np.sqrt(len(xs) / np.pi))


def _ball_in_image(img: np.ndarray, polarity: Polarity) -> tuple[np.ndarray, float]:
    """The roundest region above (bright) or below (dark) Otsu's threshold that
    does not touch the border: centre (x, y) and radius in px."""
    span = np.ptp(img)
    scaled = np.round(255 * (img - img.min()) / (span if span > 0 else 1)).astype(np.uint8)
    threshold, _ = cv2.threshold(scaled, 0, 255, cv2.THRESH_BINARY | cv2.THRESH_OTSU)
    best, best_roundness = None, _MIN_ROUNDNESS
    sides = {"bright": [True], "dark": [False], "auto": [True, False]}[polarity]
    for bright in sides:
        labels, _ = ndimage.label(ndimage.binary_fill_holes((scaled > threshold) == bright))
        border = np.unique(np.concatenate([labels[0], labels[-1], labels[:, 0], labels[:, -1]]))
        for label, where in enumerate(ndimage.find_objects(labels), start=1):
            if label in border:
                continue
            ys, xs = np.nonzero(labels[where] == label)
            if len(xs) < _MIN_BALL_PX:
                continue
            points = np.column_stack([xs, ys]).astype(np.float32)
            _, enclosing = cv2.minEnclosingCircle(points)
            roundness = len(xs) / (np.pi * max(enclosing, 1.0) ** 2)
            if roundness > best_roundness:
                centre = np.array([xs.mean() + where[1].start, ys.mean() + where[0].start])
                best, best_roundness = (centre, float(np.sqrt(len(xs) / np.pi))), roundness
    if best is None:
        raise LampCalibrationError(
            f"image: no round {'' if polarity == 'auto' else polarity + ' '}ball clear of "
            "the image border stands out from its background; give a mask or guess_mm"
        )
    return best


def _circle_px(centre_px: np.ndarray, radius_px: float, n: int) -> np.ndarray:
    phi = np.linspace(0, 2 * np.pi, n, endpoint=False)
    return centre_px + radius_px * np.column_stack([np.cos(phi), np.sin(phi)])


def _outline_px(camera: Camera, centre_mm, radius_mm: float, n: int) -> np.ndarray:
    """(n, 2) pixels of a sphere's outline: the projected circle of tangency."""
    if isinstance(camera, OrthographicCamera):
        centre_px = camera.project(centre_mm)[0][0]
        return _circle_px(centre_px, radius_mm / camera.mm_per_px, n)
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


def _fit_outline(camera: Camera, points: np.ndarray, radius_mm: float):
    """Centre, radius, kept-mask and residuals (px) of a robust fit to outline points.

    A consensus start (the triple of points a third of the outline apart that
    most points agree with, to 0.5 px) keeps arcs of false edges — a highlight
    near the rim, a marker next to the ball — from pulling the fit; then the
    least-squares fit is repeated without points beyond 3 σ (MAD).
    """
    if isinstance(camera, OrthographicCamera):
        return _fit_circle(camera, points)
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

    def fit(kept):
        centre = sphere_center_from_silhouette(camera, points[kept], radius_mm)
        to_centre = centre - origin
        dist = np.linalg.norm(to_centre)
        beta = np.arcsin(radius_mm / dist)
        residual = (np.arccos(np.clip(d @ (to_centre / dist), -1, 1)) - beta) * focal
        return centre, radius_mm, residual

    return _robust(fit, keep)


def _fit_circle(camera: OrthographicCamera, points: np.ndarray):
    """As :func:`_fit_outline` for an orthographic view: a circle (Kåsa's
    algebraic fit), its centre placed on the view axis at the depth of the
    world origin."""
    n = len(points)
    triples = (np.arange(n)[:, None] + np.array([0, n // 3, (2 * n) // 3])[None, :]) % n
    circles = [_circle_through(points[t]) for t in triples]
    off = np.array([np.abs(np.linalg.norm(points - c, axis=1) - r) for c, r in circles]).T
    keep = off[:, np.argmax(np.sum(off < 0.5, axis=0))] < 0.5

    def fit(kept):
        centre_px, radius_px = _circle_through(points[kept])
        residual = np.linalg.norm(points - centre_px, axis=1) - radius_px
        origin, axis = camera.rays(centre_px)
        centre = origin[0] + axis[0] * camera.t[2]
        return centre, radius_px * camera.mm_per_px, residual

    return _robust(fit, keep)


def _circle_through(points: np.ndarray) -> tuple[np.ndarray, float]:
    """Least-squares circle x² + y² + a x + b y + c = 0 through (n ≥ 3, 2) points."""
    A = np.column_stack([points, np.ones(len(points))])
    (a, b, c), *_ = np.linalg.lstsq(A, -np.sum(points**2, axis=1), rcond=None)
    centre = np.array([-a / 2, -b / 2])
    return centre, float(np.sqrt(max(centre @ centre - c, 0.0)))


def _robust(fit, keep: np.ndarray):
    """Refit without outliers until the kept set stays: ``fit(kept)`` gives
    (centre, radius, residual px of every point)."""
    for _ in range(10):
        if keep.sum() < _MIN_OUTLINE_POINTS:
            raise LampCalibrationError(
                f"sphere not found: only {int(keep.sum())} of {len(keep)} outline points "
                "agree on one sphere"
            )
        centre, radius, residual = fit(keep)
        sigma = 1.4826 * np.median(np.abs(residual[keep]))
        # A dark marker or wall touching the ball moves a run of neighbouring
        # points off the outline by a fraction of a pixel: too little to stand
        # out one by one, but their local median shows it.
        local = ndimage.median_filter(residual, size=_LOCAL_RUN, mode="wrap")
        new = (np.abs(residual) <= max(3 * sigma, 0.05)) & (np.abs(local) <= max(sigma, 0.03))
        if np.array_equal(new, keep):
            break
        keep = new
    return centre, radius, keep, residual
