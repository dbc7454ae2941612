import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from rig.camera import OrthographicCamera, PinholeCamera, look_at
from rig.config import default_rig_config


def _camera(dist=(0, 0, 0, 0, 0)):
    R, t = look_at([300.0, 100.0, 700.0], [0, 0, 0])
    K = np.array([[2000.0, 0, 320], [0, 2010.0, 240], [0, 0, 1]])
    return PinholeCamera(K, np.array(dist, dtype=float), R, t, 640, 480)


@given(
    st.floats(-60, 60),
    st.floats(-60, 60),
    st.floats(-20, 0),
    st.sampled_from([(0, 0, 0, 0, 0), (-0.2, 0.05, 0.001, -0.001, 0.0)]),
)
def test_rays_invert_projection(x, y, z, dist):
    cam = _camera(dist)
    pix, ok = cam.project([[x, y, z]])
    assert ok[0]
    origin, d = cam.rays(pix)
    # The ray passes through the point: distance from point to the ray line.
    p = np.array([x, y, z]) - origin
    off = np.linalg.norm(p - (p @ d[0]) * d[0])
    assert off < 1e-6


def test_matches_opencv_projection():
    cv2 = pytest.importorskip("cv2")
    cam = _camera((-0.2, 0.05, 0.001, -0.001, 0.01))
    pts = np.random.default_rng(1).uniform(-50, 50, (20, 3))
    rvec, _ = cv2.Rodrigues(cam.R)
    expected, _ = cv2.projectPoints(pts, rvec, cam.t, cam.K, cam.dist)
    assert_allclose(cam.project(pts)[0], expected[:, 0], atol=1e-8)


def test_points_behind_are_flagged():
    cam = _camera()
    _, ok = cam.project([cam.center + (cam.center - 0) * 0.5])
    assert not ok[0]


def test_default_rig_sees_whole_plate():
    config = default_rig_config()
    half = config.holder.plate_mm / 2
    corners = np.array([[sx * half, sy * half, 0] for sx in (-1, 1) for sy in (-1, 1)])
    for cam_spec in config.camera_arc.cameras:
        cam = config.camera_model(cam_spec.id)
        pix, ok = cam.project(corners)
        assert ok.all()
        assert (pix >= 0).all() and (pix[:, 0] < cam.width).all() and (pix[:, 1] < cam.height).all()


def test_camera_in_the_turned_sample_frame():
    config = default_rig_config()
    world = config.camera_model("cam3")
    turned = config.camera_model("cam3", turntable_deg=40.0)
    a = np.deg2rad(40.0)
    p_sample = np.array([[20.0, -10.0, -2.0]])
    rz = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    p_world = p_sample @ rz.T
    assert_allclose(turned.project(p_sample)[0], world.project(p_world)[0], atol=1e-9)


@pytest.mark.parametrize("scale", [0.25, 0.5, 2.0])
def test_scaled_camera_keeps_pixel_centres_on_their_rays(scale):
    cam = _camera(dist=(-0.1, 0.02, 0.001, -0.001, 0.0))
    small = cam.scaled(scale)
    assert (small.width, small.height) == (round(640 * scale), round(480 * scale))
    points = np.array([[10.0, -20.0, 0.0], [-40.0, 30.0, -2.0]])
    full, _ = cam.project(points)
    got, _ = small.project(points)
    assert_allclose(got, (full + 0.5) * scale - 0.5, atol=1e-9)
    with pytest.raises(ValueError, match="scale=0"):
        cam.scaled(0.0)


def test_orthographic_rays_are_parallel_and_project_back():
    camera = OrthographicCamera.looking_down(64, 48, mm_per_px=0.5, height_mm=300.0)
    pixels = np.array([[0.0, 0.0], [31.5, 23.5], [63.0, 10.25]])
    origins, directions = camera.rays(pixels)
    assert_allclose(directions, [[0.0, 0.0, -1.0]] * 3)
    assert_allclose(origins[:, 2], 300.0)
    # image x is world +x, image up is world +y, 0.5 mm per pixel about the centre
    assert_allclose(origins[1, :2], [0.0, 0.0], atol=1e-12)
    assert_allclose(origins[0, :2], [-15.75, 11.75])
    deeper = origins + 120.0 * directions
    assert_allclose(camera.project(deeper)[0], pixels, atol=1e-12)
    assert camera.project(deeper)[1].all() and not camera.project([[0, 0, 400.0]])[1][0]
    with pytest.raises(ValueError, match="mm_per_px"):
        OrthographicCamera(camera.R, camera.t, 0.0, 64, 48)
