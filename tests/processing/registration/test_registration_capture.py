"""register_capture: a frame as the archive holds it (rig config + step record)."""

from __future__ import annotations

import numpy as np
import pytest

from processing.registration import (
    Reason,
    RegistrationError,
    pose_plane_homography,
    register_capture,
    register_frame,
)
from rig import bonn
from rig.archive import StepRecord
from rig.config import load_rig_config


@pytest.mark.slow  # a simulated capture
def test_capture_registers_like_the_frame_with_the_config_camera(frames, rig_config):
    frame, _, _ = frames("cam3", 30.0)
    step = StepRecord(7, "btf", ("cam3",), {"cam3": (45.0, 330.0)}, (15.0, 90.0),
                      {"turntable_deg": 30.0})  # fmt: skip
    out = register_capture(frame, rig_config, step, "cam3", size=16)
    # The markers are looked for where the recorded turntable angle puts them.
    turned = rig_config.camera_model("cam3", turntable_deg=30.0)
    direct = register_frame(frame, rig_config.holder, size=16,
                            camera=rig_config.camera_model("cam3"), expected=turned)  # fmt: skip
    assert len(out.registration.detection) == len(direct.detection) >= 12
    assert out.registration.valid and out.step == 7 and out.camera == "cam3"
    np.testing.assert_array_equal(out.registration.normtexture.texture,
                                  direct.normtexture.texture)  # fmt: skip
    np.testing.assert_allclose(out.view_deg, [45.0, 330.0])
    np.testing.assert_allclose(out.light_deg, [15.0, 90.0])


def test_capture_names_a_wrong_camera(rig_config):
    step = StepRecord(3, "btf", ("cam3",), {"cam3": (45.0, 0.0)}, (0.0, 0.0))
    blank = np.zeros((64, 64), np.uint8)
    with pytest.raises(RegistrationError, match="'cam5' did not capture step 3"):
        register_capture(blank, rig_config, step, "cam5", size=8)
    odd = StepRecord(4, "btf", ("camX",), {"camX": (45.0, 0.0)}, (0.0, 0.0))
    with pytest.raises(RegistrationError, match="not in the rig config"):
        register_capture(blank, rig_config, odd, "camX", size=8)


def test_a_bonn_frame_without_markers_registers_from_the_recorded_arm_and_rail():
    """On the Bonn lab the step's recorded tool rotation and rail position pose the camera:
    a frame with no marker registers from it, with the homography that pose gives."""
    config = load_rig_config("examples/rigs/bonn.toml")
    pose = bonn.inverse(config, (85.0, 0.0), (34.0, 200.0))
    tool = bonn.plate_tool_pose(config, pose.rotation)
    rotvec_deg = np.degrees(tool.rotvec)
    actuators = {f"tool_r{c}_deg": float(v) for c, v in zip("xyz", rotvec_deg, strict=True)}
    step = StepRecord(5, "btf", ("cam0",), {"cam0": (85.0, 0.0)}, (34.0, 200.0),
                      {**actuators, "rail_deg": pose.rail_deg})  # fmt: skip
    lens = config.camera_model("cam0")
    blank = np.zeros((lens.height, lens.width), np.uint8)
    out = register_capture(blank, config, step, "cam0", size=8).registration
    assert out.valid and out.reason == Reason.FROM_RIG_POSE
    posed = bonn.camera_model(config, "cam0", pose.rotation, pose.rail_deg)
    expected = pose_plane_homography(posed, config.holder).plane_to_image
    np.testing.assert_allclose(out.homography.plane_to_image, expected, rtol=1e-9, atol=1e-12)
    moved = StepRecord(5, "btf", ("cam0",), {"cam0": (85.0, 0.0)}, (34.0, 200.0),
                       {**actuators, "rail_deg": pose.rail_deg + 3.0})  # fmt: skip
    off = register_capture(blank, config, moved, "cam0", size=8).registration
    corner = np.array([config.holder.sample_mm / 2, config.holder.sample_mm / 2, 1.0])
    seen, wanted = off.homography.plane_to_image @ corner, expected @ corner
    assert np.hypot(*(seen[:2] / seen[2] - wanted[:2] / wanted[2])) > 5.0  # px
    unrecorded = StepRecord(5, "btf", ("cam0",), {"cam0": (85.0, 0.0)}, (34.0, 200.0),
                            actuators)  # fmt: skip
    with pytest.raises(RegistrationError, match="'rail_deg'"):
        register_capture(blank, config, unrecorded, "cam0", size=8)


@pytest.mark.slow  # a simulated capture
def test_from_pose_registers_through_the_posed_camera_not_the_markers(frames, rig_config):
    frame, G, _ = frames("cam3", 30.0)
    step = StepRecord(7, "btf", ("cam3",), {"cam3": (45.0, 330.0)}, (15.0, 90.0),
                      {"turntable_deg": 30.0})  # fmt: skip
    posed = register_capture(frame, rig_config, step, "cam3", size=16, from_pose=True)
    markers = register_capture(frame, rig_config, step, "cam3", size=16)
    reg = posed.registration
    assert reg.valid and reg.reason == Reason.FROM_RIG_POSE
    assert markers.registration.reason == Reason.OK
    H = reg.homography.plane_to_image
    np.testing.assert_allclose(H / H[2, 2], G / G[2, 2], rtol=1e-9, atol=1e-9)
    # the markers' fit is a different homography, the textures nearly the same
    assert not np.allclose(markers.registration.homography.plane_to_image, H, rtol=1e-9)
    np.testing.assert_allclose(reg.normtexture.texture, markers.registration.normtexture.texture,
                               atol=2.0)  # fmt: skip


def test_from_pose_needs_no_marker_and_a_pose_to_register_from(rig_config, holder):
    step = StepRecord(2, "btf", ("cam3",), {"cam3": (45.0, 0.0)}, (15.0, 90.0),
                      {"turntable_deg": 0.0})  # fmt: skip
    lens = rig_config.camera_model("cam3")
    blank = np.zeros((lens.height, lens.width), np.uint8)
    out = register_capture(blank, rig_config, step, "cam3", size=8, from_pose=True)
    assert out.registration.valid and out.registration.reason == Reason.FROM_RIG_POSE
    with pytest.raises(RegistrationError, match="from_pose: no posed camera model"):
        register_frame(blank, holder, size=8, from_pose=True)
