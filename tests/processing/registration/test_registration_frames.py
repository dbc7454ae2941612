"""Registration of synthetic holder frames against the homography that drew them."""

from __future__ import annotations

import numpy as np
import pytest

from processing.registration import (
    Reason,
    Region,
    RegistrationError,
    blend_edges,
    detect_markers,
    marker_corners_mm,
    rectify,
    register_frame,
)
from rig.camera import PinholeCamera
from rig.geometry import texel_centers_mm
from tests.processing.registration.plate_frames import (
    camera_homography,
    project,
    render_plate,
    sample_texture,
    texel_truth,
)

N = 48


def _sample_corners(holder) -> np.ndarray:
    h = holder.sample_mm / 2
    return np.array([[-h, h], [h, h], [h, -h], [-h, -h]])


def test_marker_corner_convention(holder):
    corners = marker_corners_mm(holder)
    centers = holder.marker_centers_mm()
    s = holder.marker_mm / 2
    assert corners.shape == (len(centers), 4, 2)
    # Corner 0 top-left seen from above (−x, +y), then clockwise.
    signs = np.array([[-1, 1], [1, 1], [1, -1], [-1, -1]])
    expected = centers[:, None, :] + s * signs[None, :, :]
    np.testing.assert_allclose(corners, expected, atol=0)


@pytest.mark.parametrize(
    ("camera_id", "turntable_deg"),
    [("cam0", 0.0), ("cam3", 30.0), ("cam5", 0.0), ("cam5", 30.0), ("cam7", 200.0)],
)
def test_registration_matches_the_true_homography(frames, holder, camera_id, turntable_deg):
    frame, G, _camera = frames(camera_id, turntable_deg)
    result = register_frame(frame, holder, size=N)
    assert result.valid, result.reason
    fit = result.homography
    assert len(fit.ids) >= 6
    true_corners = project(G, marker_corners_mm(holder)[result.detection.ids])
    corner_err = np.linalg.norm(result.detection.corners_px - true_corners, axis=-1)
    assert corner_err.mean() < 0.1
    assert fit.mean_reprojection_px < 0.1
    assert fit.reprojection_px.shape == fit.ids.shape
    # The fitted homography agrees with the true one at the sample corners.
    sample_err = np.linalg.norm(
        project(fit.plane_to_image, _sample_corners(holder)) - project(G, _sample_corners(holder)),
        axis=-1,
    )
    assert sample_err.max() < 0.1
    np.testing.assert_allclose(fit.image_to_plane @ fit.plane_to_image, np.eye(3), atol=1e-9)
    # The rectified texture against the texel averages of the true texture.
    texture = result.normtexture.texture
    assert texture.dtype == np.float32
    assert texture.shape == (N, N, 3)
    assert result.normtexture.valid.all()
    truth = texel_truth(holder.sample_mm, N)
    interior = (slice(1, -1), slice(1, -1))
    err = texture[interior] - truth[interior]
    assert np.sqrt(np.mean(err**2)) < 0.006
    assert np.abs(err).max() < 0.03


def test_grey_and_integer_frames_register_alike(frames, holder):
    frame, _, _ = frames("cam3", 30.0)
    reference = register_frame(frame, holder, size=N)
    grey16 = np.round(frame.mean(axis=2) * 60000).astype(np.uint16)
    result = register_frame(grey16, holder, size=N)
    assert result.valid
    assert result.normtexture.texture.shape == (N, N, 1)
    assert result.normtexture.texture.dtype == np.float32
    np.testing.assert_allclose(
        result.homography.plane_to_image, reference.homography.plane_to_image, rtol=1e-3
    )
    expected = reference.normtexture.texture.mean(axis=2) * 60000
    np.testing.assert_allclose(result.normtexture.texture[..., 0], expected, atol=60000 * 2e-3)


def test_lens_distortion_is_undone_with_the_camera_model(holder, rig_config):
    nominal = rig_config.camera_model("cam3")
    camera = PinholeCamera(
        nominal.K, np.array([-0.25, 0.1, 0.0, 0.0, 0.0]), nominal.R, nominal.t, 1024, 768
    )
    G = camera_homography(camera, 10.0)
    frame = render_plate(holder, G, camera.width, camera.height, camera=camera, supersample=2)
    with_model = register_frame(frame, holder, size=N, camera=camera)
    assert with_model.valid
    assert with_model.homography.mean_reprojection_px < 0.1
    sample_err = np.linalg.norm(
        project(with_model.homography.plane_to_image, _sample_corners(holder))
        - project(G, _sample_corners(holder)),
        axis=-1,
    )
    assert sample_err.max() < 0.15
    truth = texel_truth(holder.sample_mm, N)
    err = with_model.normtexture.texture[1:-1, 1:-1] - truth[1:-1, 1:-1]
    assert np.sqrt(np.mean(err**2)) < 0.006
    # Ignoring the distortion leaves a visibly worse fit.
    without = register_frame(frame, holder, size=N, max_reprojection_px=50.0)
    assert without.homography.mean_reprojection_px > 5 * with_model.homography.mean_reprojection_px


def test_blank_frame_is_flagged_not_warped(holder):
    result = register_frame(np.zeros((120, 160), np.uint8), holder, size=16)
    assert not result.valid
    assert result.reason == Reason.TOO_FEW_MARKERS
    assert not result.normtexture.valid.any()
    assert not result.normtexture.texture.any()
    with pytest.raises(RegistrationError, match="TOO_FEW_MARKERS"):
        rectify(np.zeros((120, 160)), result.homography, sample_mm=100.0, size=16)


def test_region_of_interest_samples_its_own_grid(frames, holder):
    frame, _, _ = frames("cam0", 0.0)
    fit = register_frame(frame, holder, size=8).homography
    region = Region(center_mm=(12.0, -7.0), side_mm=40.0)
    out = rectify(frame, fit, sample_mm=holder.sample_mm, size=32, region=region)
    centres = texel_centers_mm(40.0, 32) + np.array([12.0, -7.0])
    point_truth = sample_texture(centres[..., 0], centres[..., 1])
    assert np.abs(out.texture - point_truth).max() < 0.02


def test_detect_rejects_bad_frames(holder):
    with pytest.raises(RegistrationError, match="frame"):
        detect_markers(np.zeros((4, 4)), holder)
    with pytest.raises(RegistrationError, match="frame"):
        detect_markers(np.zeros((20, 20, 2)), holder)


def test_blend_edges_makes_the_wrap_seamless():
    # A ramp is maximally non-tileable: its wrap jumps by the full range.
    n, b = 32, 8
    ramp = np.add.outer(np.arange(n + b), np.arange(n + b)).astype(np.float64)[..., None]
    tile = blend_edges(ramp, blend=b)
    assert tile.shape == (n, n, 1)
    assert tile.dtype == np.float32
    wrap_cols = np.abs(tile[:, 0] - tile[:, -1]).max()
    wrap_rows = np.abs(tile[0] - tile[-1]).max()
    # Without blending the wrap jumps by n − 1 per axis; blended, it steps like the interior.
    assert np.abs(ramp[:n, 0] - ramp[:n, n - 1]).max() == n - 1
    assert wrap_cols <= 2.0
    assert wrap_rows <= 2.0
    np.testing.assert_array_equal(blend_edges(ramp[:n, :n], blend=0), ramp[:n, :n])
    with pytest.raises(RegistrationError, match="blend"):
        blend_edges(ramp, blend=30)
