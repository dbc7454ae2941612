"""Per-texel near-lamp irradiance (``processing.offline.texel_light``) against the
simulator's own lamp model (``sim.shading.LightSource``, independent code)."""

import numpy as np
import pytest

from processing.offline.texel_light import IRRADIANCE_FLOOR, lamp_positions, texel_irradiance
from rig.calfile import CalibrationFile, LampResult
from rig.config import RigConfig
from rig.geometry import texel_centers_mm
from rig.kinematics import lamp_position_mm
from sim.shading import LightSource

SAMPLE_MM, N = 100.0, 16


def _rig(**lamp):
    config = RigConfig()
    lamps = [x.model_copy(update=lamp) for x in config.light_arc.lamps]
    return config.model_copy(
        update={"light_arc": config.light_arc.model_copy(update={"lamps": tuple(lamps)})}
    )


def _simulated(config, lamp, arc, turntable, kind="point", cutoff=90.0):
    """E cos θ on the plane, texel over centre, of the simulator's lamp at the step's position."""
    source = LightSource(lamp_position_mm(config, lamp, arc_deg=arc, turntable_deg=turntable),
                         kind, 1.0, cutoff)  # fmt: skip
    xy = texel_centers_mm(SAMPLE_MM, N).reshape(-1, 2)
    points = np.column_stack([xy, np.zeros(len(xy))])
    dirs, e = source.incident(np.vstack([points, [[0.0, 0.0, 0.0]]]))
    e = e * dirs[:, 2]
    return (e[:-1] / e[-1]).reshape(N, N)


STEPS = [("lamp3", 0.0, 0.0), ("lamp3", 40.0, 110.0), ("lamp6", -25.0, 300.0)]


@pytest.mark.parametrize(("lamp", "arc", "turntable"), STEPS)
def test_a_near_lamp_gives_each_texel_the_simulators_irradiance(lamp, arc, turntable):
    config = RigConfig()
    positions = lamp_positions(config, None)
    ratio, floored = texel_irradiance(positions, config, lamp, sample_mm=SAMPLE_MM, size=N,
                                      arc_deg=arc, turntable_deg=turntable)  # fmt: skip
    np.testing.assert_allclose(ratio, _simulated(config, lamp, arc, turntable), rtol=1e-10)
    assert not floored.any()
    assert ratio.max() / ratio.min() > 1.2  # 650 mm from a 100 mm sample: not uniform


def test_directional_lamps_are_not_placed():
    assert lamp_positions(_rig(kind="directional"), None) is None


def test_calibrated_positions_are_used_and_recorded():
    config = RigConfig()
    nominal_mm = lamp_position_mm(config, "lamp3", arc_deg=0.0, turntable_deg=0.0)
    moved = nominal_mm + np.array([0.0, 30.0, -20.0])
    calibration = CalibrationFile(lamps={"lamp3": LampResult(position_mm=tuple(moved))})
    positions = lamp_positions(config, calibration, "white session (2026-01-01)")
    np.testing.assert_array_equal(positions.positions_mm["lamp3"], moved)
    assert "calibrated lamp positions, white session (2026-01-01)" in positions.source
    assert "nominal" in positions.source  # the other lamps: the config's geometry
    nominal = lamp_positions(config, None)
    assert "calibrated" not in nominal.source
    a, _ = texel_irradiance(positions, config, "lamp3", sample_mm=SAMPLE_MM, size=N,
                            arc_deg=0.0, turntable_deg=0.0)  # fmt: skip
    b, _ = texel_irradiance(nominal, config, "lamp3", sample_mm=SAMPLE_MM, size=N,
                            arc_deg=0.0, turntable_deg=0.0)  # fmt: skip
    assert np.abs(a - b).max() > 1e-3


def test_texels_outside_a_spot_cone_are_floored_and_flagged():
    config = _rig(kind="spot", spot_cutoff_deg=3.0)
    positions = lamp_positions(config, None)
    ratio, floored = texel_irradiance(positions, config, "lamp3", sample_mm=SAMPLE_MM, size=N,
                                      arc_deg=0.0, turntable_deg=0.0)  # fmt: skip
    want = _simulated(config, "lamp3", 0.0, 0.0, kind="spot", cutoff=3.0)
    assert floored.any() and not floored.all()
    np.testing.assert_array_equal(floored, want < IRRADIANCE_FLOOR)
    np.testing.assert_allclose(ratio[~floored], want[~floored], rtol=1e-10)
    assert np.all(ratio[floored] == IRRADIANCE_FLOOR)


def test_a_lamp_near_grazing_stays_finite():
    config = _rig(theta_deg=89.0)
    positions = lamp_positions(config, None)
    ratio, floored = texel_irradiance(positions, config, "lamp3", sample_mm=SAMPLE_MM, size=N,
                                      arc_deg=0.0, turntable_deg=0.0)  # fmt: skip
    assert np.all(np.isfinite(ratio)) and np.all(ratio > 0) and not floored.any()
    np.testing.assert_allclose(ratio, _simulated(config, "lamp3", 0.0, 0.0), rtol=1e-10)


def test_a_lamp_below_the_horizon_lights_nothing_and_is_flagged():
    config = RigConfig()
    below = lamp_position_mm(config, "lamp3", arc_deg=0.0, turntable_deg=0.0) * (1, 1, -1)
    positions = lamp_positions(config, CalibrationFile(lamps={"lamp3": LampResult(
        position_mm=tuple(below))}), "a session")  # fmt: skip
    ratio, floored = texel_irradiance(positions, config, "lamp3", sample_mm=SAMPLE_MM, size=N,
                                      arc_deg=0.0, turntable_deg=0.0)  # fmt: skip
    assert floored.all() and np.all(ratio == IRRADIANCE_FLOOR)


def test_a_bonn_lab_is_not_placed():
    assert lamp_positions(RigConfig(kind="bonn", bonn={}), None) is None


def test_a_calibration_of_lamps_this_rig_does_not_have_is_not_used():
    elsewhere = CalibrationFile(lamps={"lampX": LampResult(position_mm=(0.0, 0.0, 500.0))})
    positions = lamp_positions(RigConfig(), elsewhere, "another rig's session")
    assert "lampX" not in positions.positions_mm
    assert positions.source == "the rig config's lamp geometry (nominal)"
