"""Camera calibration on the simulated rig, against the simulator's cameras.

One calibration session (the ChArUco wedge, two cameras, 12 turntable angles,
noise + lens distortion + vignetting, half-size images) is captured through the
daemon and the real drivers; the calibration reads only the archive. The
simulator's rig config is the truth; the calibration never reads its
intrinsics or poses.
"""

import numpy as np
import pytest
from typer.testing import CliRunner

from calibration.plans import camera_plan
from calibration.sessions import calibrate_cameras
from orchestrator.cli import app
from orchestrator.local import replay_local, run_local
from rig.archive import Archive, FrameFormat
from rig.calfile import load_calibration
from rig.clock import VirtualClock
from rig.config import RigConfig, default_rig_config
from rig.kinematics import rotate_z
from sim.calibration import target_scene
from sim.rig import SimulatedRig

# Simulated sessions, rendered targets or fits of seconds each: make test only, not make quick.
pytestmark = pytest.mark.slow

CAMERAS = ("cam0", "cam2")
# Stated tolerances at half size (f = 1500 px, 800 mm away); see docs/calibration.md.
RMS_PX = 0.1
FOCAL_REL = 0.005
POSITION_MM = 3.0
FORMATS = {"cam0": FrameFormat(768, 1024, 3, "uint8")}


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    out = tmp_path_factory.mktemp("calibration")
    archive = out / "cameras.zarr"
    plan = out / "cameras.plan.toml"
    config = default_rig_config()
    plan.write_text(camera_plan(config, poses=12, cameras=CAMERAS, archive=str(archive)))
    clock = VirtualClock()
    with SimulatedRig(target_scene("cameras", config), clock=clock) as rig:
        final = run_local(plan, rig.rig_config(), archive=archive, clock=clock)
    assert final["state"] == "done", final
    cameras, failed = calibrate_cameras(archive)
    with Archive.open(archive, mode="r") as recorded:
        truth = RigConfig.model_validate(recorded.rig_config)
    return archive, cameras, failed, truth


def test_cameras_match_the_simulators(session):
    _, cameras, failed, truth = session
    assert not failed
    assert set(cameras) == set(CAMERAS)
    for camera_id, cam in cameras.items():
        true = truth.camera_model(camera_id)
        true_centre = -true.R.T @ true.t
        assert cam.rms_px < RMS_PX, camera_id
        assert abs(cam.K[0, 0] / true.K[0, 0] - 1) < FOCAL_REL, (camera_id, cam.K, true.K)
        assert abs(cam.K[1, 1] / true.K[1, 1] - 1) < FOCAL_REL, camera_id
        assert np.linalg.norm(cam.centre_mm - true_centre) < POSITION_MM, (
            camera_id, cam.centre_mm, true_centre,
        )  # fmt: skip
        assert cam.axis_tilt_deg is not None and cam.axis_tilt_deg < 0.5, camera_id


def test_grazing_views_are_left_out_with_the_reason(session):
    _, cameras, _, _ = session
    oblique = cameras["cam2"]  # θ = 30°, the wedge leans 40°: some views are grazing
    reasons = list(oblique.rejected.values())
    assert reasons, "the oblique camera kept every view"
    assert all("grazing" in r or "not found" in r for r in reasons), reasons
    assert all(np.isfinite(e) for e in oblique.per_image_rms_px.values())


def test_replayed_session_gives_the_same_numbers(session, tmp_path):
    archive, cameras, _, _ = session
    replay = tmp_path / "replay.zarr"
    assert replay_local(archive, out=replay)["state"] == "done"
    again, _ = calibrate_cameras(replay)
    for camera_id, cam in cameras.items():
        np.testing.assert_array_equal(again[camera_id].K, cam.K)
        np.testing.assert_array_equal(again[camera_id].t, cam.t)


def test_cli_writes_the_calibration_file_and_applies_it(session, tmp_path):
    archive, cameras, _, _ = session
    target = tmp_path / "session.zarr"
    with Archive.create(target, plan={}, rig_config={}, cameras=FORMATS):
        pass
    out = tmp_path / "rig-calibration.toml"
    args = ["calibrate", "cameras", "--from", str(archive), "--out", str(out)]
    result = CliRunner().invoke(app, [*args, "--apply", str(target)])
    assert result.exit_code == 0, result.output
    assert "grazing" in result.output
    cal = load_calibration(out)
    assert cal.cameras_provenance is not None and cal.cameras_provenance.archive.endswith(".zarr")
    assert cal.cameras["cam0"].K[0][0] == pytest.approx(cameras["cam0"].K[0, 0])
    assert out.with_suffix(".cameras.png").stat().st_size > 0
    with Archive.open(target, mode="r") as applied:
        assert applied.calibration_version == 1
        assert set(applied.calibration["cameras"]) == set(CAMERAS)


def test_processing_uses_the_applied_calibration(session, tmp_path):
    from processing.offline import frame_camera

    archive, cameras, _, _ = session
    target = tmp_path / "session.zarr"
    config = default_rig_config()
    with Archive.create(target, plan={}, rig_config={}, cameras=FORMATS) as created:
        nominal = frame_camera(created, config, "cam0", 30.0)
    runner = CliRunner()
    args = ["calibrate", "cameras", "--from", str(archive), "--out", str(tmp_path / "c.toml")]
    assert runner.invoke(app, [*args, "--apply", str(target)]).exit_code == 0
    with Archive.open(target, mode="r") as applied:
        lens = frame_camera(applied, config, "cam0", 30.0)
    # calibrated at half size, read here at full size: K doubles (pixel centres kept)
    assert lens.K[0, 0] == pytest.approx(2 * cameras["cam0"].K[0, 0])
    assert lens.K[0, 0] != pytest.approx(nominal.K[0, 0], rel=1e-6)
    # the sample turned by 30° sees the calibrated camera turned by −30°
    centre = -lens.R.T @ lens.t
    np.testing.assert_allclose(centre, rotate_z(cameras["cam0"].centre_mm, -30.0), atol=1e-9)


def test_an_unknown_target_is_refused_with_the_valid_ones():
    result = CliRunner().invoke(app, ["calibrate", "lens"])
    assert result.exit_code == 2
    assert "cameras, lamps, laser, response" in result.output
