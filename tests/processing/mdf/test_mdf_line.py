"""Laser line detection in the reference region: accuracy, glints, missing lines."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.ndimage import binary_erosion

from processing.mdf import (
    LineReason,
    MdfError,
    detect_laser_line,
    plate_points,
    profile_axis_for,
)
from tests.budgets import scaled
from tests.processing.mdf.mdf_scenes import CONFIG, frames, region, scan


def true_line_error_px(line, normal, offset, reg):
    """Largest distance of the detected line from the true strip, over ±60 mm along it."""
    m = normal[:2] / np.linalg.norm(normal[:2])
    base = m * offset / np.linalg.norm(normal[:2])
    pts = base + np.linspace(-60, 60, 13)[:, None] * np.array([-m[1], m[0]])
    return np.max(np.abs(pts @ line.normal - line.rho_mm)) / reg.footprint_mm


def axis_for(arc):
    s = scan(arc).source_mm
    return profile_axis_for(region().camera, [-s[1], s[0]])


@pytest.mark.parametrize("arc", [90.0, 162.0, 306.0])
@pytest.mark.parametrize("method", ["gaussian", "centroid", "blais_rioux"])
def test_line_matches_the_true_strip(arc, method):
    reg, sc = region(), scan(arc)
    errors = []
    for i in range(10, len(sc.offset) - 10, 7):
        line = detect_laser_line(
            frames(arc)[i], reg, profile_axis=axis_for(arc), threshold=40.0, method=method
        )
        assert line.valid, line
        errors.append(true_line_error_px(line, sc.normal[i], sc.offset[i], reg))
    assert np.median(errors) < 0.1
    assert np.max(errors) < 0.5


def test_glint_on_the_plate_is_rejected():
    arc, i = 162.0, 40
    reg, sc = region(), scan(arc)
    frame = frames(arc)[i].copy()
    clean = detect_laser_line(frame, reg, profile_axis=axis_for(arc), threshold=40.0)
    # A saturated specular hot spot on the plate, deep inside the region and
    # as far from the strip as the region allows.
    inner = binary_erosion(reg.mask, np.ones((13, 13), bool))
    ys, xs = np.nonzero(inner)
    pts, _ = plate_points(reg.camera, np.column_stack([xs, ys]))
    far = np.argmax(np.abs(pts @ clean.normal - clean.rho_mm))
    yy, xx = np.mgrid[0 : frame.shape[0], 0 : frame.shape[1]]
    frame[(yy - ys[far]) ** 2 + (xx - xs[far]) ** 2 <= 5] = 255
    hit = detect_laser_line(frame, reg, profile_axis=axis_for(arc), threshold=40.0)
    assert hit.valid
    assert hit.candidates > clean.candidates  # the glint produced candidates...
    assert hit.inliers <= clean.inliers
    assert true_line_error_px(hit, sc.normal[i], sc.offset[i], reg) < 0.1  # ...left out


def test_glint_pulls_a_least_squares_fit_off():
    """The control for the test above: averaging the glint in would fail it."""
    arc, i = 162.0, 40
    reg, sc = region(), scan(arc)
    frame = frames(arc)[i].copy()
    frame[reg.mask & (np.arange(frame.shape[1])[None, :] < 30)] = 255  # a wide glare patch
    axis = axis_for(arc)
    robust = detect_laser_line(frame, reg, profile_axis=axis, threshold=40.0)
    assert robust.valid and robust.inliers < robust.candidates  # the glare left out
    assert true_line_error_px(robust, sc.normal[i], sc.offset[i], reg) < 0.5
    # A tolerance wider than the glare's distance from the strip (but narrower than the
    # candidates' spread, so pairs still define lines) takes every candidate in.
    averaged = detect_laser_line(frame, reg, profile_axis=axis, threshold=40.0, inlier_tol_px=40)
    assert averaged.valid and averaged.inliers == averaged.candidates == robust.candidates
    assert true_line_error_px(averaged, sc.normal[i], sc.offset[i], reg) > 1.0


def test_no_line_in_the_reference_region_is_flagged():
    reg = region()
    dark = np.full(reg.mask.shape, 12, np.uint8)
    line = detect_laser_line(dark, reg, profile_axis=0, threshold=40.0)
    assert line.reason == LineReason.NO_CANDIDATES
    assert not line.valid
    assert np.all(line.normal == 0)


def test_scattered_bright_pixels_give_no_consensus():
    reg = region()
    rng = np.random.default_rng(1)
    frame = np.full(reg.mask.shape, 10, np.uint8)
    ys, xs = np.nonzero(reg.mask)
    pick = rng.choice(len(ys), 60, replace=False)
    frame[ys[pick], xs[pick]] = 255
    line = detect_laser_line(frame, reg, profile_axis=0, threshold=40.0, sigma_px=0)
    assert line.reason in (LineReason.NO_CONSENSUS, LineReason.SHORT, LineReason.NO_CANDIDATES)


def test_bad_inputs_name_the_problem():
    reg = region()
    with pytest.raises(MdfError, match="does not match the reference region"):
        detect_laser_line(np.zeros((10, 10)), reg, profile_axis=0, threshold=1.0)
    with pytest.raises(MdfError, match="profile_axis"):
        detect_laser_line(np.zeros(reg.mask.shape), reg, profile_axis=2, threshold=1.0)
    with pytest.raises(MdfError, match="reference region is empty"):
        type(reg).from_holder(reg.camera, sample_mm=170.0, plate_mm=180.0, margin_mm=4.0)


@scaled(0.4)
@given(
    seed=st.integers(0, 2**31),
    level=st.integers(0, 255),
    noise=st.floats(0, 80),
    axis=st.sampled_from([0, 1]),
)
def test_any_frame_gives_a_finite_line_or_a_flag(seed, level, noise, axis):
    reg = region()
    rng = np.random.default_rng(seed)
    frame = np.clip(level + rng.normal(0, noise, reg.mask.shape), 0, 255).astype(np.uint8)
    line = detect_laser_line(frame, reg, profile_axis=axis, threshold=40.0)
    assert np.all(np.isfinite(line.normal)) and np.isfinite(line.rho_mm)
    if line.valid:
        assert abs(np.linalg.norm(line.normal) - 1) < 1e-9
        assert line.inliers >= 8 and line.span_mm >= 20
    else:
        assert np.all(line.normal == 0)


def test_default_config_is_the_one_scanned():
    assert CONFIG.laser.mount_theta_deg == (45.0,)
