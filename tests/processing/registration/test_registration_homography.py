"""Homography fits from exact, noisy, partial and degenerate marker sets."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from processing.registration import (
    MarkerDetection,
    Reason,
    RegistrationError,
    fit_plane_homography,
    marker_corners_mm,
    pose_plane_homography,
)
from rig.camera import PinholeCamera
from rig.config import Holder
from tests.processing.registration.plate_frames import camera_homography, project


def _detection(holder, G, ids, noise_px=0.0, seed=0) -> MarkerDetection:
    ids = np.asarray(ids, dtype=np.int64)
    corners = project(G, marker_corners_mm(holder)[ids])
    corners = corners + np.random.default_rng(seed).normal(0, noise_px, corners.shape)
    return MarkerDetection(ids, corners, np.zeros(0, np.int64))


@pytest.fixture(scope="module")
def oblique(rig_config):
    return camera_homography(rig_config.camera_model("cam5"), 30.0)


def test_exact_corners_give_the_exact_homography(holder, oblique):
    fit = fit_plane_homography(_detection(holder, oblique, range(16)), holder)
    assert fit.valid
    np.testing.assert_allclose(fit.plane_to_image / fit.plane_to_image[2, 2], oblique, rtol=1e-9)
    assert fit.mean_reprojection_px < 1e-9


def test_too_few_markers_are_flagged(holder, oblique):
    fit = fit_plane_homography(_detection(holder, oblique, [1, 2]), holder)
    assert fit.reason == Reason.TOO_FEW_MARKERS
    assert not fit.valid
    assert not fit.plane_to_image.any()


def test_markers_on_one_side_are_ill_conditioned(holder, oblique):
    # Exact corners, but extrapolating from one side of the plate to the
    # far corners of the sample would amplify any corner noise ~10×.
    fit = fit_plane_homography(_detection(holder, oblique, [0, 1, 2, 3]), holder)
    assert fit.reason == Reason.ILL_CONDITIONED
    assert fit.noise_gain > 2.0
    full = fit_plane_homography(_detection(holder, oblique, range(16)), holder)
    assert full.noise_gain < 0.5


def test_near_collinear_points_are_flagged(rig_config):
    holder = Holder(marker_mm=0.5)  # tiny markers in a row: points on a line
    G = camera_homography(rig_config.camera_model("cam0"), 0.0)
    fit = fit_plane_homography(_detection(holder, G, [0, 1, 2, 3]), holder)
    assert fit.reason == Reason.COLLINEAR_MARKERS
    assert not fit.plane_to_image.any()


def test_a_wrong_marker_is_dropped_as_outlier(holder, oblique):
    detection = _detection(holder, oblique, range(16), noise_px=0.02)
    corners = detection.corners_px.copy()
    corners[5] += 6.0  # one marker's corners 8.5 px off
    bad = MarkerDetection(detection.ids, corners, detection.rejected_ids)
    fit = fit_plane_homography(bad, holder)
    assert fit.valid
    assert fit.outlier_ids.tolist() == [5]
    assert 5 not in fit.ids
    assert fit.mean_reprojection_px < 0.05


def test_noisy_corners_above_the_limit_are_flagged(holder, oblique):
    fit = fit_plane_homography(_detection(holder, oblique, range(16), noise_px=1.2), holder)
    assert fit.reason == Reason.HIGH_REPROJECTION
    assert fit.mean_reprojection_px > 1.0


@pytest.mark.parametrize(
    ("option", "value"),
    [("min_markers", 0), ("max_noise_gain", -1.0), ("outlier_px", float("nan"))],
)
def test_bad_options_are_named(holder, oblique, option, value):
    with pytest.raises(RegistrationError, match=option):
        fit_plane_homography(_detection(holder, oblique, range(16)), holder, **{option: value})


def test_unknown_marker_ids_are_refused(holder, oblique):
    detection = _detection(holder, oblique, [0, 1, 2])
    bad = MarkerDetection(np.array([0, 1, 99]), detection.corners_px, detection.rejected_ids)
    with pytest.raises(RegistrationError, match="99"):
        fit_plane_homography(bad, holder)


@given(
    ids=st.lists(st.integers(0, 15), min_size=0, max_size=16, unique=True),
    noise_px=st.floats(0.0, 5.0),
    scramble=st.booleans(),
    seed=st.integers(0, 2**16),
)
def test_any_marker_subset_gives_a_finite_flagged_or_accurate_fit(
    holder, oblique, ids, noise_px, scramble, seed
):
    detection = _detection(holder, oblique, sorted(ids), noise_px, seed)
    if scramble:  # corners in random places: garbage from a broken detector
        rng = np.random.default_rng(seed)
        corners = rng.uniform(-50, 1100, detection.corners_px.shape)
        detection = MarkerDetection(detection.ids, corners, detection.rejected_ids)
    fit = fit_plane_homography(detection, holder)
    assert isinstance(fit.reason, Reason)
    for value in (fit.plane_to_image, fit.image_to_plane, fit.reprojection_px):
        assert np.all(np.isfinite(value))
    assert np.isfinite(fit.mean_reprojection_px)
    assert np.isfinite(fit.noise_gain)
    assert fit.valid == (fit.reason == Reason.OK)
    if fit.valid:
        assert len(fit.ids) >= 3
        assert fit.mean_reprojection_px <= 1.0
        if not scramble:
            h = holder.sample_mm / 2
            square = np.array([[-h, h], [h, h], [h, -h], [-h, -h]])
            err = np.linalg.norm(
                project(fit.plane_to_image, square) - project(oblique, square), axis=1
            )
            # The conditioning check bounds the error at the sample corners.
            assert err.max() < 6 * fit.noise_gain * max(noise_px, 1e-3) + 1e-6
    else:
        assert not fit.plane_to_image.any()


def test_a_posed_camera_gives_the_plate_homography_without_markers(rig_config, holder):
    lens = rig_config.camera_model("cam5")
    camera = PinholeCamera(lens.K, np.zeros(5), lens.R, lens.t, lens.width, lens.height)
    fit = pose_plane_homography(camera, holder)
    assert fit.valid and fit.reason == Reason.FROM_RIG_POSE and len(fit.ids) == 0
    plate = marker_corners_mm(holder).reshape(-1, 2)
    want, in_front = camera.project(np.column_stack([plate, np.zeros(len(plate))]))
    assert in_front.all()
    np.testing.assert_allclose(project(fit.plane_to_image, plate), want, atol=1e-9)
    np.testing.assert_allclose(fit.image_to_plane @ fit.plane_to_image, np.eye(3), atol=1e-9)


def test_a_pose_looking_away_from_the_sample_is_flagged(rig_config, holder):
    lens = rig_config.camera_model("cam5")
    turned = np.diag([1.0, -1.0, -1.0])  # half a turn about the camera's x: sample behind
    camera = PinholeCamera(lens.K, lens.dist, turned @ lens.R, turned @ lens.t, 64, 64)
    fit = pose_plane_homography(camera, holder)
    assert not fit.valid and fit.reason == Reason.SAMPLE_NOT_VISIBLE


def test_plane_points_map_to_the_pixels_opencv_gives():
    from processing.registration._rectify import _footprint_px, _to_pixels

    H = np.array([[4.1, 0.3, 250.0], [-0.2, 3.7, 190.0], [1e-4, -2e-4, 1.0]])
    xy = np.random.default_rng(3).uniform(-40, 40, (500, 2))
    expected = cv2.perspectiveTransform(xy[None], H)[0]
    np.testing.assert_allclose(_to_pixels(H, xy, None), expected, rtol=0, atol=1e-9)
    # The footprint of a texel step is the largest step seen in the image.
    grid = np.stack(np.meshgrid(np.linspace(-40, 40, 9), np.linspace(-40, 40, 9)), -1)
    fx, fy = _footprint_px(H, grid, 0.5, None)
    pts = grid.reshape(-1, 2)
    base = cv2.perspectiveTransform(pts[None], H)[0]
    steps = [cv2.perspectiveTransform((pts + d)[None], H)[0] - base for d in ([0.5, 0], [0, 0.5])]
    assert fx == pytest.approx(np.linalg.norm(steps[0], axis=1).max(), abs=1e-9)
    assert fy == pytest.approx(np.linalg.norm(steps[1], axis=1).max(), abs=1e-9)
