"""Lamp directions from a distant mirror-sphere setup, as real captures come.

The frames are shaped like a public mirror-sphere capture: a chrome ball that
reflects a lit room (bright, shaded) on a dark cloth, 8-bit with noise, the
lamp's highlight clipped, no calibrated camera — an ``OrthographicCamera``
looking down, lamp directions in its frame (x right, y up, z to the camera).
The rig's own case, a dark ball against the lit plate, runs the same way.
"""

import numpy as np
import pytest
from numpy.testing import assert_allclose

from calibration import sphere_silhouette
from calibration.lamps import (
    LampCalibrationError,
    SphereOutline,
    SphereShot,
    lamp_direction,
    locate_sphere,
    sphere_ray,
)
from calibration.report import lamp_report
from calibration.sessions import LampRun
from rig.calfile import LampResult
from rig.camera import OrthographicCamera, PinholeCamera, look_at
from rig.geometry import angular_distance_deg, direction_vector
from rig.targets import MirrorSphere

SIZE = 200
CENTRE_PX = np.array([97.3, 104.6])
RADIUS_PX = 61.2
CAMERA = OrthographicCamera.looking_down(SIZE, SIZE)
SPHERE = MirrorSphere()  # its radius serves pinhole fits only
LAMPS = [(20.0, 30.0), (45.0, 160.0), (60.0, 275.0), (35.0, 0.0)]


def _highlight_px(lamp, centre_px=CENTRE_PX, radius_px=RADIUS_PX):
    """Where a distant lamp's highlight sits under an orthographic view from +z."""
    normal = lamp + np.array([0.0, 0.0, 1.0])
    normal /= np.linalg.norm(normal)
    return centre_px + radius_px * np.array([normal[0], -normal[1]])  # image y is down


def _frame(lamp=None, *, ball="bright", seed=0, centre_px=CENTRE_PX, amplitude=600.0):
    """8-bit frame, 4× supersampled: the ball, its background, the highlight (clipped)."""
    rng = np.random.default_rng(seed)
    sub = (np.arange(SIZE * 4) + 0.5) / 4 - 0.5
    xx, yy = np.meshgrid(sub, sub)
    r2 = ((xx - centre_px[0]) ** 2 + (yy - centre_px[1]) ** 2) / RADIUS_PX**2
    on_ball = r2 < 1
    if ball == "bright":  # reflects a lit room: brighter towards the top, on a dark cloth
        inside, outside = 130 - 40 * (yy - centre_px[1]) / RADIUS_PX, 6.0
    else:  # black chrome against the lit plate
        inside, outside = 12.0 + 0 * yy, 170.0
    image = np.where(on_ball, inside, outside)
    if lamp is not None:
        hx, hy = _highlight_px(lamp, centre_px)
        image = image + on_ball * amplitude * np.exp(-((xx - hx) ** 2 + (yy - hy) ** 2) / 8.0)
    image = image.reshape(SIZE, 4, SIZE, 4).mean(axis=(1, 3))
    image = image + rng.normal(0, 2.0, image.shape)
    return np.clip(np.round(image), 0, 255).astype(np.uint8)


def _mask(centre_px=CENTRE_PX):
    yy, xx = np.mgrid[0:SIZE, 0:SIZE]
    inside = (xx - centre_px[0]) ** 2 + (yy - centre_px[1]) ** 2 < RADIUS_PX**2
    return np.where(inside, 255, 0).astype(np.uint8)


@pytest.mark.parametrize("ball", ["bright", "dark"])
def test_locate_sphere_finds_a_bright_or_dark_ball_without_a_guess(ball):
    found = locate_sphere(CAMERA, _frame(ball=ball), radius_mm=SPHERE.radius_mm)
    assert_allclose(CAMERA.project(found.centre_mm)[0][0], CENTRE_PX, atol=0.05)
    assert found.radius_mm == pytest.approx(RADIUS_PX, abs=0.05)
    assert found.coverage_deg > 350


def test_a_given_polarity_must_match_the_ball():
    with pytest.raises(LampCalibrationError, match="no round dark ball"):
        locate_sphere(CAMERA, _frame(ball="bright"), radius_mm=25.0, polarity="dark")


def test_sphere_silhouette_follows_a_bright_ball_outline():
    phi = np.linspace(0, 2 * np.pi, 90, endpoint=False)
    circle = np.column_stack([np.cos(phi), np.sin(phi)])
    points = sphere_silhouette(_frame(), CENTRE_PX + (RADIUS_PX + 3) * circle, search_px=6)
    distance = np.linalg.norm(points - CENTRE_PX, axis=1)
    assert len(points) > 80
    assert_allclose(distance, RADIUS_PX, atol=0.2)


@pytest.mark.parametrize("ball", ["bright", "dark"])
def test_distant_lamps_from_clipped_highlights_within_a_tenth_of_a_degree(ball):
    for theta, phi in LAMPS:
        lamp = direction_vector(theta, phi)
        shot = SphereShot(f"L{phi:g}", "photo", CAMERA, _frame(lamp, ball=ball))
        ray = sphere_ray(shot, SPHERE, saturation_level=255)
        assert ray.highlight.clipped
        assert angular_distance_deg(ray.direction, lamp) < 0.1, (theta, phi)


def test_a_mask_or_a_known_centre_places_the_sphere():
    lamp = direction_vector(45.0, 160.0)
    image = _frame(lamp, ball="bright")
    # Data sets ship the ball's mask (uint8 0/255) or its centre and radius.
    masked = SphereShot("L", "photo", CAMERA, image, mask=_mask())
    known = SphereOutline.given(CAMERA.rays(CENTRE_PX)[0][0], RADIUS_PX)
    given = SphereShot("L", "photo", CAMERA, image, sphere=known)
    for shot in (masked, given):
        ray = sphere_ray(shot, SPHERE, saturation_level=255)
        assert angular_distance_deg(ray.direction, lamp) < 0.3


def test_several_highlights_give_a_spread_and_one_says_it_has_none():
    lamp = direction_vector(35.0, 70.0)
    rays = []
    for seed, shift in enumerate([(0, 0), (6.5, -4.0), (-7.0, 3.5), (3.0, 8.0)]):
        centre = CENTRE_PX + shift
        shot = SphereShot("L", "photo", CAMERA, _frame(lamp, seed=seed, centre_px=centre))
        rays.append(sphere_ray(shot, SPHERE, saturation_level=255))
    many = lamp_direction(rays)
    assert angular_distance_deg(many.direction, lamp) < 0.2
    assert 0 < many.spread_deg < 0.3
    assert many.uncertainty_deg == pytest.approx(many.spread_deg / np.sqrt(3))
    one = lamp_direction(rays[:1])
    assert one.spread_deg is None and one.uncertainty_deg is None
    report = lamp_report(
        {"L": LampResult(direction=one.direction.tolist(), observations=1)},
        LampRun({"L": 1}, {}),
        {},
    )
    assert "one ray" in report


def test_pinhole_camera_bright_ball_on_dark_background():
    """The rig's camera model with a bright ball: the cone fit, no guess given."""
    K = np.array([[900.0, 0, 159.5], [0, 900.0, 119.5], [0, 0, 1]])
    R, t = look_at([0.0, -300.0, 700.0], [0.0, 0.0, 0.0])
    camera = PinholeCamera(K, np.zeros(5), R, t, 320, 240)
    centre = np.array([5.0, 8.0, SPHERE.radius_mm])
    yy, xx = np.mgrid[0:240, 0:320]
    origin, d = camera.rays(np.column_stack([xx.ravel(), yy.ravel()]))
    oc = origin - centre
    b = d @ oc
    hit = (b**2 - (oc @ oc - SPHERE.radius_mm**2) > 0).reshape(240, 320)
    image = np.where(hit, 140.0, 5.0)
    found = locate_sphere(camera, image, radius_mm=SPHERE.radius_mm, centre_z_mm=SPHERE.radius_mm)
    assert_allclose(found.centre_mm, centre, atol=0.3)
