"""Radiometric response on the simulated rig, against the simulator's tone curve.

An exposure bracket of the ChArUco wedge (6 exposures over 5 stops, two
turntable angles) is captured through the daemon from a camera whose tone
curve is gamma 2.2 (effect ``response``), with noise, saturation, vignetting
and lens distortion on; Debevec & Malik's curve must match the inverse of the
simulator's (``sim.sensor.inverse_response``) after both are normalised at 128.
"""

import numpy as np
import pytest
from typer.testing import CliRunner

from calibration.plans import response_plan
from calibration.response import ResponseError, calibrate_response, merge_bracket
from calibration.sessions import calibrate_responses
from orchestrator.cli import app
from orchestrator.local import run_local
from rig.calfile import load_calibration
from rig.clock import VirtualClock
from rig.config import default_rig_config
from sim.calibration import target_scene
from sim.rig import SimulatedRig
from sim.sensor import inverse_response

# Simulated sessions, rendered targets or fits of seconds each: make test only, not make quick.
pytestmark = pytest.mark.slow

VALUES = slice(32, 241)  # 8-bit values where one step is < 7 % of the linear signal
# The 1 % for every value; measured median ≤ 0.3 %, worst ≤ 0.8 % (docs/calibration.md).
MEDIAN_TOLERANCE, MAX_TOLERANCE = 0.004, 0.01
# One exposure linearised alone against the merge: noise biases both (hat weights, clipping).
MERGE_TOLERANCE = 0.03


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    archive = tmp_path_factory.mktemp("response") / "response.zarr"
    plan = archive.with_suffix(".plan.toml")
    config = default_rig_config()
    plan.write_text(response_plan(config, archive=str(archive)))
    scene = target_scene("response", config, supersample=1)
    clock = VirtualClock()
    with SimulatedRig(scene, clock=clock) as rig:
        assert run_local(plan, rig.rig_config(), archive=archive, clock=clock)["state"] == "done"
    return archive, scene.spec.params("response").gamma


def _truth(gamma) -> np.ndarray:
    linear = inverse_response(np.arange(256), bit_depth=8, gamma=gamma)
    return linear / linear[128]


def test_the_curve_matches_the_cameras(session):
    archive, gamma = session
    curves, exposures, failed = calibrate_responses(archive)
    assert not failed and exposures == 6
    curve = curves["cam0"].curve
    truth = _truth(gamma)
    for c in range(curve.shape[1]):
        error = np.abs(curve[VALUES, c] / truth[VALUES] - 1)
        assert np.median(error) < MEDIAN_TOLERANCE, (c, np.median(error))
        assert error.max() < MAX_TOLERANCE, (c, error.max(), VALUES.start + int(error.argmax()))
    assert np.all(np.isfinite(curve)) and np.all(curve > 0)


def test_merged_radiance_is_linear_and_flags_saturation(session):
    from rig.archive import Archive

    archive, _ = session
    curves, _, _ = calibrate_responses(archive)
    with Archive.open(archive, mode="r") as recorded:
        step = recorded.step_table()[0]
        images = [recorded.read_frame(step.index, "cam0", sub) for sub in range(6)]
    merged = merge_bracket(images, step.exposures_s, curves["cam0"])
    assert np.all(np.isfinite(merged.radiance))
    # Each exposure alone, linearised and divided by its time, agrees with the merge
    # where it is well exposed: the curve made the camera linear.
    for image, t in zip(images, step.exposures_s, strict=True):
        ok = merged.valid & np.all((image > 40) & (image < 220), axis=-1)
        alone = curves["cam0"].linearize(image)[ok] / t
        assert abs(np.median(alone / merged.radiance[ok]) - 1) < MERGE_TOLERANCE
    # The brightest exposures clip the white board; the shortest do not.
    assert (images[-1] == 255).any() and not (images[0] == 255).any()


def test_one_exposure_is_refused():
    image = np.zeros((8, 8, 3), np.uint8)
    with pytest.raises(ResponseError, match="at least 2 exposures"):
        calibrate_response([image], [0.01])


def test_a_scene_without_shades_is_refused():
    flat = [np.full((16, 16, 3), 255, np.uint8), np.full((16, 16, 3), 255, np.uint8)]
    with pytest.raises(ResponseError, match="vary over the bracket"):
        calibrate_response(flat, [0.01, 0.02])


def test_calibrate_on_a_fresh_clone_makes_its_folder(tmp_path, monkeypatch):
    """`rig calibrate response --sim` where no calibrations/ folder exists yet."""
    monkeypatch.chdir(tmp_path)
    result = CliRunner().invoke(app, ["calibrate", "response", "--sim", "--scale", "0.1"])
    assert result.exit_code == 0, result.output
    assert (tmp_path / "calibrations" / "response.plan.toml").is_file()
    assert load_calibration(tmp_path / "calibrations" / "calibration.toml").response


def test_the_calibration_file_may_go_to_a_new_folder(session, tmp_path):
    archive, _ = session
    out = tmp_path / "new" / "cal.toml"
    result = CliRunner().invoke(
        app, ["calibrate", "response", "--from", str(archive), "--out", str(out)]
    )
    assert result.exit_code == 0, result.output
    assert load_calibration(out).response and out.with_suffix(".response.png").is_file()
