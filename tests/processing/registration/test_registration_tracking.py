"""Markers refined where the rig's pose expects them, and the compiled texel sampling."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from processing.registration import (
    detect_markers,
    expected_corners_px,
    marker_corners_mm,
    register_frame,
    track_markers,
)
from processing.registration._sampling import box_bilinear, project_box_bilinear
from tests.processing.registration.plate_frames import project


@pytest.mark.parametrize(("camera_id", "turntable_deg"), [("cam0", 0.0), ("cam5", 30.0)])
def test_tracked_markers_are_the_detected_ones(frames, rig_config, camera_id, turntable_deg):
    frame, G, _ = frames(camera_id, turntable_deg)
    holder = rig_config.holder
    turned = rig_config.camera_model(camera_id, turntable_deg=turntable_deg)
    tracked = track_markers(frame, holder, expected_corners_px(turned, holder))
    detected = detect_markers(frame, holder)
    np.testing.assert_array_equal(tracked.ids, detected.ids)
    assert len(tracked) >= 12
    # Both end in the same edge fits, from starts a fraction of a pixel apart: as far
    # from the true corners, mean and worst (measured 0.0492 / 0.151 px against
    # 0.0492 / 0.156 px at cam5, 30°).
    truth = project(G, marker_corners_mm(holder)[tracked.ids])
    tracked_px = np.linalg.norm(tracked.corners_px - truth, axis=2)
    detected_px = np.linalg.norm(detected.corners_px - truth, axis=2)
    assert tracked_px.mean() <= detected_px.mean() + 0.002
    assert tracked_px.max() <= detected_px.max() + 0.01
    np.testing.assert_allclose(tracked.corners_px, detected.corners_px, atol=0.1)


def test_a_misplaced_expectation_finds_nothing_and_the_detector_takes_over(frames, rig_config):
    """The plate expected a quarter turn off: every marker is expected where another one is
    (the layout is square), its edges are found but not its bits, so none is kept, and
    register_frame registers the frame with the detector as if nothing were expected."""
    frame, _, camera = frames("cam0", 0.0)
    holder = rig_config.holder
    quarter = rig_config.camera_model("cam0", turntable_deg=90.0)
    assert len(track_markers(frame, holder, expected_corners_px(camera, holder))) >= 12
    assert len(track_markers(frame, holder, expected_corners_px(quarter, holder))) == 0
    direct = register_frame(frame, holder, size=16, camera=camera)
    fallback = register_frame(frame, holder, size=16, camera=camera, expected=quarter)
    assert fallback.valid
    np.testing.assert_array_equal(fallback.detection.ids, direct.detection.ids)
    np.testing.assert_array_equal(fallback.normtexture.texture, direct.normtexture.texture)


def test_box_bilinear_is_map_coordinates_averaged():
    rng = np.random.default_rng(3)
    frame = rng.integers(0, 256, (20, 30, 3), dtype=np.uint8)
    n_sub = 4
    pixels = np.column_stack([rng.uniform(-3, 33, 400), rng.uniform(-3, 23, 400)])
    out = np.zeros((100, 3))
    box_bilinear(frame, pixels, n_sub, out)
    for c in range(3):
        values = ndimage.map_coordinates(
            frame[:, :, c].astype(np.float64), [pixels[:, 1], pixels[:, 0]], order=1,
            mode="nearest",
        )  # fmt: skip
        np.testing.assert_allclose(out[:, c], values.reshape(100, n_sub).mean(axis=1), atol=1e-9)


def test_projected_sampling_flags_texels_off_the_frame():
    rng = np.random.default_rng(4)
    frame = rng.normal(size=(20, 30, 1))
    H = np.array([[2.0, 0.1, 14.0], [-0.05, -2.0, 9.0], [1e-3, 2e-3, 1.0]])
    centers = np.column_stack([rng.uniform(-12, 12, 50), rng.uniform(-8, 8, 50)])
    sub = np.array([[-0.25, -0.25], [0.25, -0.25], [-0.25, 0.25], [0.25, 0.25]])
    out, valid = np.zeros((50, 1)), np.ones(50, bool)
    project_box_bilinear(frame, H, centers, sub, out, valid)
    points = (centers[:, None, :] + sub[None]).reshape(-1, 2)
    hom = np.column_stack([points, np.ones(len(points))]) @ H.T
    pix = hom[:, :2] / hom[:, 2:]
    inside = ((pix >= -0.5) & (pix <= np.array([29.5, 19.5]))).all(axis=1)
    np.testing.assert_array_equal(valid, inside.reshape(50, 4).all(axis=1))
    assert valid.any() and not valid.all()
    expected = np.zeros((50, 1))
    box_bilinear(frame, pix, 4, expected)
    np.testing.assert_allclose(out, expected, atol=1e-9)


def test_the_compiled_footprint_is_the_lens_models_without_distortion(rig_config):
    from processing.registration._rectify import _footprint_px
    from processing.registration._sampling import homography_footprint_px
    from rig.geometry import texel_centers_mm
    from tests.processing.registration.plate_frames import camera_homography

    camera = rig_config.camera_model("cam6")
    H = camera_homography(camera, 75.0)
    grid = texel_centers_mm(100.0, 40)
    expected = _footprint_px(H, grid, 2.5, None)
    compiled = homography_footprint_px(H, grid.reshape(-1, 2), 2.5)
    np.testing.assert_allclose(compiled, expected, rtol=1e-12)
    assert expected[0] != pytest.approx(expected[1], rel=0.01)  # an oblique view: x and y differ


@pytest.mark.parametrize("dtype", [">u2", "<f2", ">f8"])
def test_frames_of_any_byte_order_and_half_floats_register_as_native_ones(frames, holder, dtype):
    """The compiled passes read native dtypes only: a big-endian or float16 frame (as a file
    may hold it) registers exactly as its native copy."""
    frame, _, camera = frames("cam0", 0.0)  # float, 0 … 1
    odd = (frame * (60000 if dtype == ">u2" else 1)).astype(dtype)
    native = odd.astype(odd.dtype.newbyteorder("=") if dtype != "<f2" else np.float32)
    a = register_frame(odd, holder, size=16, camera=camera, expected=camera)
    b = register_frame(native, holder, size=16, camera=camera, expected=camera)
    assert a.valid and len(a.detection) >= 12
    np.testing.assert_array_equal(a.normtexture.texture, b.normtexture.texture)
