"""Calibrated lamp intensities and distances in the per-texel irradiance: each lamp's
irradiance at the sample's centre over the rig config's, against the simulator's lamp."""

import numpy as np
import pytest

from processing.offline.texel_light import lamp_positions, texel_irradiance
from rig.calfile import CalibrationFile, LampResult
from rig.config import RigConfig
from rig.kinematics import lamp_position_mm
from sim.shading import LightSource


def _centre_irradiance(position, intensity: float) -> float:
    """E cos θ at the turntable centre of the simulator's point lamp."""
    dirs, e = LightSource(np.asarray(position), "point", intensity).incident(np.zeros((1, 3)))
    return float(e[0] * dirs[0, 2])


def test_each_lamps_centre_gain_is_its_calibrated_irradiance_over_the_mean():
    config = RigConfig()
    nominal = {k: lamp_position_mm(config, k, arc_deg=0.0, turntable_deg=0.0)
               for k in ("lamp1", "lamp3")}  # fmt: skip
    built = {"lamp1": nominal["lamp1"] * 1.02, "lamp3": nominal["lamp3"] + [4.0, -3.0, 2.0]}
    power = {"lamp1": 1.1, "lamp3": 0.9}  # relative: their scale is the white session's
    calibration = CalibrationFile(lamps={
        k: LampResult(position_mm=tuple(built[k]), intensity=power[k]) for k in built
    })  # fmt: skip
    positions = lamp_positions(config, calibration, "lamp session")
    truth = {k: _centre_irradiance(built[k], power[k]) / _centre_irradiance(nominal[k], 1.0)
             for k in built}  # fmt: skip
    mean = np.mean(list(truth.values()))
    for lamp in built:
        assert positions.centre_gain[lamp] == pytest.approx(truth[lamp] / mean, rel=1e-12)
        ratio, _ = texel_irradiance(positions, config, lamp, sample_mm=100.0, size=2,
                                    arc_deg=0.0, turntable_deg=0.0)  # fmt: skip
        # the four texels around the centre: the gain times their geometry, within 1 %
        assert ratio.mean() == pytest.approx(positions.centre_gain[lamp], rel=0.01)
    assert positions.centre_gain["lamp1"] != pytest.approx(1.0, abs=0.02)


def test_without_a_calibration_every_lamp_keeps_the_configs_irradiance():
    positions = lamp_positions(RigConfig(), None)
    assert positions.centre_gain == {}
