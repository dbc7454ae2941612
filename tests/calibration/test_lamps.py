import numpy as np
import pytest
from numpy.testing import assert_allclose

from calibration.lamps import (
    LampCalibrationError,
    find_highlight,
    flat_fields,
    reflected_ray,
    sphere_center_from_silhouette,
    triangulate_lamp,
)
from rig.config import default_rig_config
from rig.geometry import angular_distance_deg, direction_vector

CONFIG = default_rig_config()
CAMERA = CONFIG.camera_model("cam2")
RADIUS = 25.0


def _unit(v):
    return v / np.linalg.norm(v)


def _mirror_point(center, lamp_dir=None, lamp_pos=None):
    """The sphere point whose normal halves camera and lamp (fixed-point iteration)."""
    p = center + RADIUS * _unit(CAMERA.center - center)
    for _ in range(200):
        to_lamp = lamp_dir if lamp_dir is not None else _unit(lamp_pos - p)
        p = center + RADIUS * _unit(_unit(CAMERA.center - p) + to_lamp)
    return p


def _silhouette(center, n=24):
    # Rays tangent to the sphere: a cone around the centre direction.
    axis = _unit(center - CAMERA.center)
    dist = np.linalg.norm(center - CAMERA.center)
    beta = np.arcsin(RADIUS / dist)
    u = _unit(np.cross(axis, [0, 0, 1]))
    w = np.cross(axis, u)
    angles = np.linspace(0, 2 * np.pi, n, endpoint=False)
    rays = np.cos(beta) * axis + np.sin(beta) * (
        np.cos(angles)[:, None] * u + np.sin(angles)[:, None] * w
    )
    pts = CAMERA.center + rays * dist * np.cos(beta)
    return CAMERA.project(pts)[0]


def _image(center, highlight_px, *, amplitude=200.0, sigma=1.5):
    h, w = CAMERA.height, CAMERA.width
    yy, xx = np.mgrid[0:h, 0:w]
    c_px = CAMERA.project([center])[0][0]
    r_px = np.max(np.linalg.norm(_silhouette(center) - c_px, axis=1))
    mask = (xx - c_px[0]) ** 2 + (yy - c_px[1]) ** 2 < (0.97 * r_px) ** 2
    blob = amplitude * np.exp(
        -((xx - highlight_px[0]) ** 2 + (yy - highlight_px[1]) ** 2) / (2 * sigma**2)
    )
    img = np.where(mask, 10.0 + blob, 0.0)
    return np.clip(np.round(img), 0, 255).astype(np.uint8), mask


@pytest.mark.parametrize(("theta", "phi"), [(30, 0), (45, 200), (60, 90), (0, 0)])
def test_distant_lamp_direction_within_half_a_degree(theta, phi):
    center = np.array([10.0, -5.0, RADIUS])
    lamp = direction_vector(theta, phi)
    p = _mirror_point(center, lamp_dir=lamp)
    px = CAMERA.project([p])[0][0]
    image, mask = _image(center, px)
    fitted_center = sphere_center_from_silhouette(CAMERA, _silhouette(center), RADIUS)
    assert_allclose(fitted_center, center, atol=1e-6)
    hl = find_highlight(image, mask, saturation_level=255)
    assert not hl.clipped
    assert np.linalg.norm(hl.pixel - px) < 0.1
    _, direction = reflected_ray(CAMERA, hl.pixel, fitted_center, RADIUS)
    assert angular_distance_deg(direction, lamp) < 0.5


def test_near_lamp_position_within_one_percent():
    lamp = 650.0 * direction_vector(45, 120)
    points, dirs = [], []
    for center in ([-40.0, -40.0, RADIUS], [40.0, 30.0, RADIUS], [0.0, 60.0, RADIUS]):
        center = np.array(center)
        p = _mirror_point(center, lamp_pos=lamp)
        image, mask = _image(center, CAMERA.project([p])[0][0])
        c = sphere_center_from_silhouette(CAMERA, _silhouette(center), RADIUS)
        hl = find_highlight(image, mask, saturation_level=255)
        point, direction = reflected_ray(CAMERA, hl.pixel, c, RADIUS)
        points.append(point)
        dirs.append(direction)
    got = triangulate_lamp(points, dirs)
    assert np.linalg.norm(got.position_mm - lamp) < 0.01 * np.linalg.norm(lamp)
    assert got.rays == 3


def test_clipped_highlight_is_flagged_and_still_centred():
    center = np.array([0.0, 0.0, RADIUS])
    p = _mirror_point(center, lamp_dir=direction_vector(40, 10))
    px = CAMERA.project([p])[0][0]
    image, mask = _image(center, px, amplitude=2000.0, sigma=2.0)
    hl = find_highlight(image, mask, saturation_level=255)
    assert hl.clipped
    assert np.linalg.norm(hl.pixel - px) < 0.5


def test_parallel_rays_and_dark_images_are_refused():
    with pytest.raises(LampCalibrationError, match="nearly parallel"):
        triangulate_lamp([[0, 0, 0], [1, 0, 0]], [[0, 0, 1], [0, 0, 1]])
    with pytest.raises(LampCalibrationError, match="dark"):
        find_highlight(np.zeros((8, 8)), np.ones((8, 8), bool), saturation_level=255)
    with pytest.raises(LampCalibrationError, match=r"lamp image\(s\) \[1\] are dark"):
        flat_fields(np.stack([np.ones((16, 16)), np.zeros((16, 16))]))


def test_flat_fields_recover_relative_intensities_and_falloff():
    yy, xx = np.mgrid[0:40, 0:60]
    falloff = 1.0 / (1 + ((xx - 30) ** 2 + (yy - 20) ** 2) / 2000.0)
    intensities = np.array([1.0, 0.8, 0.55])
    images = intensities[:, None, None] * falloff[None]
    got = flat_fields(images)
    assert_allclose(got.intensity, intensities / intensities.max(), rtol=0.01)
    assert_allclose(got.falloff[1] / got.falloff[1][20, 30], falloff / falloff[20, 30], rtol=1e-5)
