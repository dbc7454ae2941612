import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from calibration.laser import LaserCalibrationError, laser_plane_angle, strip_offset_mm
from rig.config import default_rig_config
from rig.kinematics import laser_plane


def _strip_on_plane(normal, d, height, direction):
    # Points of the sheet n·x = d on the horizontal plane z = height.
    n = np.asarray(normal)
    across = np.array([-direction[1], direction[0]])
    # Solve n_xy·(s·across) = d − n_z·h for s; then sample along the strip.
    s = (d - n[2] * height) / (n[:2] @ across)
    t = np.linspace(-40, 40, 9)[:, None]
    return s * across + t * np.asarray(direction)


@pytest.mark.parametrize("tilt", [-5.0, 0.0, 4.0])
@pytest.mark.parametrize("arc", [0.0, 90.0])
def test_two_heights_recover_the_true_sheet_angle(tilt, arc):
    config = default_rig_config()
    n, d = laser_plane(config, arc_deg=arc, mount=0, tilt_deg=tilt, turntable_deg=0)
    direction = np.array([-np.sin(np.deg2rad(arc)), np.cos(np.deg2rad(arc))])
    heights = [0.0, 20.0]
    offsets = [strip_offset_mm(_strip_on_plane(n, d, h, direction), direction) for h in heights]
    got = laser_plane_angle(heights, offsets)
    across = np.array([-direction[1], direction[0], 0.0])
    # True angle between the sheet and z = 0, signed like the fit's convention.
    true = np.rad2deg(np.arccos(abs(n[2])))
    if n @ across * n[2] < 0:
        true = 180.0 - true
    assert_allclose(got.angle_deg, true, atol=1e-9)
    assert got.residual_mm == 0.0


def test_general_fit_from_many_heights_reports_residual():
    rng = np.random.default_rng(3)
    heights = np.array([0.0, 5.0, 10.0, 15.0, 20.0])
    angle = 52.0
    offsets = 3.0 - heights / np.tan(np.deg2rad(angle)) + rng.normal(0, 0.02, 5)
    got = laser_plane_angle(heights, offsets, offset_std_mm=0.02)
    assert abs(got.angle_deg - angle) < 0.1  # docs/calibration.md's tolerance
    assert 0 < got.residual_mm < 0.05
    assert got.heights == 5
    assert 0 < got.angle_std_deg < 0.2


def test_nearly_equal_heights_are_refused():
    with pytest.raises(LaserCalibrationError, match="higher second plane"):
        laser_plane_angle([10.0, 10.2], [0.0, -0.2])


@pytest.mark.parametrize(
    ("heights", "offsets", "match"),
    [([0.0], [0.0], "≥ 2"), ([0, 10], [0, np.nan], "finite"), ([0, 1, 2], [0, 1], "same number")],
)
def test_bad_input_is_named(heights, offsets, match):
    with pytest.raises(LaserCalibrationError, match=match):
        laser_plane_angle(heights, offsets)


@given(st.floats(1, 179), st.floats(1, 100), st.floats(-50, 50))
def test_angle_is_finite_and_exact_for_any_sheet(angle, h, c):
    offsets = [c, c - h / np.tan(np.deg2rad(angle))]
    got = laser_plane_angle([0.0, h], offsets)
    assert np.isfinite(got.angle_deg)
    assert np.isfinite(got.angle_std_deg)
    assert_allclose(got.angle_deg, angle, atol=1e-6)
