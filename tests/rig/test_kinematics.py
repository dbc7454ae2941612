import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from rig.config import Axis, default_rig_config
from rig.errors import KinematicsError
from rig.geometry import Sampling, angular_distance_deg, direction_vector
from rig.kinematics import forward, inverse, laser_plane, wrap_into

CONFIG = default_rig_config()
REACHABLE_THETAS = sorted({abs(c.theta_deg) for c in CONFIG.camera_arc.cameras})


@given(
    st.sampled_from(REACHABLE_THETAS),
    st.floats(0, 359.9),
    st.sampled_from(REACHABLE_THETAS),
    st.floats(0, 359.9),
)
def test_inverse_then_forward_hits_reachable_pairs(tv, pv, tl, pl):
    pose = inverse(CONFIG, (tv, pv), (tl, pl))
    assert pose.view_residual_deg < 1e-6
    assert pose.light_residual_deg < 1e-6
    view, light = forward(
        CONFIG,
        turntable_deg=pose.turntable_deg,
        arc_deg=pose.arc_deg,
        camera=pose.camera,
        lamp=pose.lamp,
    )
    assert angular_distance_deg(direction_vector(*view), direction_vector(tv, pv)) < 1e-6
    assert angular_distance_deg(direction_vector(*light), direction_vector(tl, pl)) < 1e-6


@given(st.floats(0, 89), st.floats(0, 359.9), st.floats(0, 89), st.floats(0, 359.9))
def test_residual_is_the_true_angle_to_what_the_rig_does(tv, pv, tl, pl):
    pose = inverse(CONFIG, (tv, pv), (tl, pl))
    view, light = forward(
        CONFIG,
        turntable_deg=pose.turntable_deg,
        arc_deg=pose.arc_deg,
        camera=pose.camera,
        lamp=pose.lamp,
    )
    got_v = angular_distance_deg(direction_vector(*view), direction_vector(tv, pv))
    got_l = angular_distance_deg(direction_vector(*light), direction_vector(tl, pl))
    assert_allclose(got_v, pose.view_residual_deg, atol=1e-6)
    assert_allclose(got_l, pose.light_residual_deg, atol=1e-6)
    # Nothing better exists among the cameras: the residual is the distance in θ
    # to the nearest camera ring.
    assert pose.view_residual_deg <= min(abs(tv - t) for t in REACHABLE_THETAS) + 1e-6


def test_forward_turntable_rotates_azimuth():
    view, light = forward(CONFIG, turntable_deg=30, arc_deg=100, camera="cam2", lamp="lamp3")
    assert_allclose(view, [30, 330])
    assert_allclose(light, [45, 70])


def test_free_axis_stays_put():
    pose = inverse(CONFIG, (0, 0), (0, 0), current=(123.0, 45.0))
    assert pose.turntable_deg == 123.0
    assert pose.arc_deg == 45.0


def test_wrap_into_range():
    axis = Axis(speed_deg_s=1, accel_deg_s2=1, min_deg=0, max_deg=360)
    wrapped, ok = wrap_into(np.array([-10.0, 370.0, 180.0]), axis)
    assert_allclose(wrapped, [350, 10, 180])
    assert ok.all()
    narrow = Axis(speed_deg_s=1, accel_deg_s2=1, min_deg=0, max_deg=90)
    wrapped, ok = wrap_into(np.array([180.0]), narrow)
    assert not ok[0]


def test_unknown_ids_are_named():
    with pytest.raises(Exception, match="unknown camera 'camX'"):
        forward(CONFIG, turntable_deg=0, arc_deg=0, camera="camX", lamp="lamp0")
    with pytest.raises(KinematicsError, match=r"laser0\.\.laser0"):
        forward(CONFIG, turntable_deg=0, arc_deg=0, camera="cam0", lamp="laser7")


def test_move_time_trapezoid():
    axis = Axis(speed_deg_s=10, accel_deg_s2=20)
    assert_allclose(axis.move_time_s(0), 0)
    # Triangular below v²/a = 5°, trapezoidal above.
    assert_allclose(axis.move_time_s(5), 2 * np.sqrt(5 / 20))
    assert_allclose(axis.move_time_s(100), 100 / 10 + 10 / 20)


def test_laser_plane_contains_the_source_and_sweeps():
    _, d0 = laser_plane(CONFIG, arc_deg=0, mount=0, tilt_deg=0, turntable_deg=0)
    assert_allclose(d0, 0, atol=1e-9)  # passes through the turntable centre
    xs = []
    for tilt in (-4, 0, 4):
        n, d = laser_plane(CONFIG, arc_deg=0, mount=0, tilt_deg=tilt, turntable_deg=0)
        assert_allclose(np.linalg.norm(n), 1)
        assert n[2] >= 0
        xs.append(d / n[0])  # where the strip crosses the x axis on z = 0
    assert xs[0] > xs[1] > xs[2]  # the strip sweeps monotonically


def test_h2_on_default_rig_is_exact():
    s = Sampling.named("H2")
    for v in s.directions[::7]:
        for light in s.directions[::5]:
            pose = inverse(CONFIG, tuple(v), tuple(light))
            assert pose.view_residual_deg < 1e-6 and pose.light_residual_deg < 1e-6
