"""Laser-plane calibration on the simulated rig, against its kinematics.

The step block (bands at known heights) is scanned through the daemon and the
real NXT driver; the sheet's angle to the reference plane comes from the
strip's offsets between bands (seed 001 §3.2). The truth is the simulator's
sheet (``rig.kinematics.laser_plane``) at the recorded tilt.
"""

import numpy as np
import pytest

from calibration.laser import LaserCalibrationError, band_offsets, laser_plane_angle, strip_pixels
from calibration.plans import laser_plan
from calibration.sessions import calibrate_laser
from orchestrator.local import run_local
from processing.mdf import profile_axis_for
from rig.archive import Archive
from rig.clock import VirtualClock
from rig.config import RigConfig, default_rig_config
from rig.kinematics import laser_plane
from sim.calibration import target_scene
from sim.rig import SimulatedRig
from sim.simulator import Simulator

# Simulated sessions, rendered targets or fits of seconds each: make test only, not make quick.
pytestmark = pytest.mark.slow

ANGLE_DEG = 0.1  # the tolerance


def _rig(heights=(0.0, 10.0), sweep_deg=2.0) -> RigConfig:
    config = default_rig_config()
    targets = config.targets.model_copy(
        update={"laser": config.targets.laser.model_copy(update={"heights_mm": heights})}
    )
    laser = config.laser.model_copy(update={"sweep_deg": sweep_deg})
    return config.model_copy(update={"targets": targets, "laser": laser})


def _true_angle(config, tilt_deg) -> float:
    normal, _ = laser_plane(config, arc_deg=0.0, mount=0, tilt_deg=tilt_deg, turntable_deg=0.0)
    return float(np.degrees(np.arccos(normal[2])))


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    archive = tmp_path_factory.mktemp("laser") / "laser.zarr"
    plan = archive.with_suffix(".plan.toml")
    config = _rig()
    plan.write_text(laser_plan(config, archive=str(archive)))
    clock = VirtualClock()
    with SimulatedRig(target_scene("laser", config, supersample=1), clock=clock) as rig:
        assert run_local(plan, rig.rig_config(), archive=archive, clock=clock)["state"] == "done"
    with Archive.open(archive, mode="r") as recorded:
        truth = RigConfig.model_validate(recorded.rig_config)
    return archive, truth


def test_two_heights_give_the_sheet_angle(session):
    archive, truth = session
    results, frames = calibrate_laser(archive)
    found = results[0]
    assert abs(found.angle_deg - _true_angle(truth, found.tilt_deg)) < ANGLE_DEG
    assert abs(found.tilt_deg) < 0.2  # the frame nearest the sheet's rest position
    used = [f for f in frames if f.angle is not None]
    assert len(used) >= 5
    for f in used:  # every frame's angle, at its own tilt
        assert abs(f.angle.angle_deg - _true_angle(truth, f.tilt_deg)) < ANGLE_DEG


def _frame_angle(config, tilt=0.0):
    scene = target_scene("laser", config, supersample=1)
    with Simulator(scene) as sim:
        frame = sim.render_state("cam0", laser=True, laser_tilt_deg=tilt, exposure_s=0.005)
        camera = scene.rig.camera_model("cam0")
    pixels = strip_pixels(frame.image, profile_axis=profile_axis_for(camera, [0.0, 1.0]))
    heights, offsets, _ = band_offsets(
        pixels, camera, scene.rig.targets.laser, sample_mm=scene.rig.holder.sample_mm
    )
    return laser_plane_angle(heights, offsets)


def test_more_heights_fit_a_line_with_its_residual():
    config = _rig(heights=(0.0, 4.0, 8.0, 12.0, 16.0))
    got = _frame_angle(config, tilt=0.5)
    assert got.heights == 5
    assert abs(got.angle_deg - _true_angle(config, 0.5)) < ANGLE_DEG
    assert 0 < got.residual_mm < 0.05  # a planar sheet: offsets on one line
    assert 0 < got.angle_std_deg < ANGLE_DEG


def test_nearly_equal_heights_are_refused():
    with pytest.raises(LaserCalibrationError, match=r"span 0\.300 mm"):
        _frame_angle(_rig(heights=(0.0, 0.3)))


def test_a_dark_frame_is_refused():
    with pytest.raises(LaserCalibrationError, match="dark"):
        strip_pixels(np.zeros((20, 30, 3), np.uint8), profile_axis=0)


def test_mdf_processing_takes_the_calibrated_angle(tmp_path):
    from processing.offline.mdf import _calibrated_offset_deg
    from rig.archive import FrameFormat
    from rig.calfile import CalibrationFile, LaserResult

    config = default_rig_config()
    measured = LaserResult(angle_deg=45.3, angle_std_deg=0.01, residual_mm=0.0, heights=2,
                           tilt_deg=1.0)  # fmt: skip
    calibration = CalibrationFile(laser={"mount0": measured}).model_dump(mode="json")
    formats = {"cam0": FrameFormat(8, 8, 3, "uint8")}
    with Archive.create(tmp_path / "s.zarr", plan={}, rig_config={}, cameras=formats,
                        calibration=calibration) as archive:  # fmt: skip
        offset = _calibrated_offset_deg(archive, config, 0, 30.0, 10.0)
        assert _calibrated_offset_deg(archive, config, 1, 30.0, 10.0) == 0.0  # no such mount
    assert offset == pytest.approx(45.3 - _true_angle(config, 1.0), abs=1e-9)
