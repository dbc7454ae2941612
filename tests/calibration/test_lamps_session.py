"""`rig calibrate lamps` end to end on the simulated rig: two sessions through the
daemon (mirror sphere, white target), computed from their archives alone,
against the simulator's lamps (``rig.kinematics.lamp_position_mm``)."""

import numpy as np
import pytest
from typer.testing import CliRunner

from orchestrator.cli import app
from rig.calfile import load_calibration
from rig.config import RigConfig, default_rig_config, write_rig_config
from rig.geometry import angular_distance_deg
from rig.kinematics import lamp_position_mm
from rig.material import read_flat_field

# Simulated sessions, rendered targets or fits of seconds each: make test only, not make quick.
pytestmark = pytest.mark.slow

LAMPS = (
    {"id": "sun45", "theta_deg": 45.0, "kind": "directional", "intensity": 1.0},
    {"id": "near30", "theta_deg": 30.0, "kind": "point", "intensity": 0.8},
    {"id": "near60", "theta_deg": -60.0, "kind": "point", "intensity": 1.2},
)


@pytest.fixture(scope="module")
def calibrated(tmp_path_factory):
    out = tmp_path_factory.mktemp("lamps")
    data = default_rig_config().model_dump(mode="json")
    data["light_arc"]["lamps"] = list(LAMPS)
    config = RigConfig.model_validate(data)
    rig_path = write_rig_config(config, out / "rig.toml")
    cal = out / "cal.toml"
    args = ["calibrate", "lamps", "--sim", "--config", str(rig_path),
            "--cameras", "cam0,cam2,cam4", "--archive", str(out / "lamps.zarr"), "--out", str(cal)]
    # three cameras: the near lamps' distances to ~0.3 %, which their intensities need twice
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.output
    return config, load_calibration(cal), result.output, cal


def test_distant_lamp_direction(calibrated):
    config, cal, *_ = calibrated
    truth = lamp_position_mm(config, "sun45", arc_deg=0.0, turntable_deg=0.0)
    found = np.array(cal.lamps["sun45"].direction)
    assert angular_distance_deg(found, truth) < 0.5  # the tolerance


@pytest.mark.parametrize("lamp", ["near30", "near60"])
def test_near_lamp_position(calibrated, lamp):
    config, cal, *_ = calibrated
    truth = lamp_position_mm(config, lamp, arc_deg=0.0, turntable_deg=0.0)
    found = np.array(cal.lamps[lamp].position_mm)
    assert np.linalg.norm(found - truth) < 0.01 * np.linalg.norm(truth)


def test_near_lamp_intensities(calibrated):
    _, cal, output, _ = calibrated
    ratio = cal.lamps["near30"].intensity / cal.lamps["near60"].intensity
    assert ratio == pytest.approx(0.8 / 1.2, rel=0.01)
    assert cal.lamps_provenance is not None
    assert "near60" in output and "not calibrated" not in output


def test_flat_field_maps_are_written_beside_the_file(calibrated):
    _, cal, _, path = calibrated
    assert cal.lamps_flat_field is not None
    maps = read_flat_field(path.parent / cal.lamps_flat_field)
    falloff, lamps = maps.falloff, list(maps.lamps)
    assert sorted(lamps) == sorted(lamp["id"] for lamp in LAMPS)
    height, width = falloff.shape[1:]
    assert np.all(np.isfinite(falloff))
    centre = falloff[:, height // 2, width // 2]
    assert np.allclose(centre, 1.0, atol=0.05)  # normalised at the target's centre
