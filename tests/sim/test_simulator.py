"""Simulator API: frames, timing, life cycle."""

import numpy as np
import pytest

from rig.clock import VirtualClock
from sim import Simulator, World
from tests.sim.sim_scenes import small_scene


def test_frame_types_and_metadata(bumps_sim):
    frame = bumps_sim.render_state("cam1", lamps_on=["lamp1"], exposure_s=0.02)
    assert frame.image.dtype == np.uint8 and frame.image.shape == (96, 128, 3)
    assert frame.signal.dtype == np.float32
    meta = frame.metadata
    assert meta["lamps_on"] == ["lamp1"] and meta["exposure_s"] == 0.02
    with pytest.raises(ValueError, match="exposure_s"):
        bumps_sim.render_state("cam1", exposure_s=0)
    with pytest.raises(Exception, match="unknown lamp"):
        bumps_sim.render_state("cam1", lamps_on=["lamp99"])


def test_exposure_scales_the_signal(bumps_sim):
    a = bumps_sim.render_state("cam2", lamps_on=["lamp2"], exposure_s=0.01)
    b = bumps_sim.render_state("cam2", lamps_on=["lamp2"], exposure_s=0.02)
    np.testing.assert_allclose(b.signal, 2 * a.signal, rtol=1e-5)


def test_mono_sixteen_bit_camera():
    cams = [{"id": "mono", "theta_deg": 30, "channels": 1, "bit_depth": 12}]
    scene = small_scene("flat", rig={"overrides": {"camera_arc": {"cameras": cams}}})
    with Simulator(scene) as sim:
        frame = sim.render_state("mono", lamps_on=["lamp0"])
        assert frame.image.dtype == np.uint16 and frame.image.ndim == 2
        assert 0 < frame.image.max() <= 4095


@pytest.mark.parametrize("timed", [True, False])
def test_capture_reports_and_spends_motion_time(timed):
    scene = small_scene("flat", effects=["motion_timing"] if timed else [])
    clock = VirtualClock()
    world = World(scene.rig, clock)
    world.set_lamp("lamp2", True)
    with Simulator(scene) as sim:
        frame = sim.capture(world, "cam1", turntable_deg=90.0, arc_deg=30.0, exposure_s=0.1)
    axis = scene.rig.turntable.axis
    expected_move = float(axis.move_time_s(90.0))  # the turntable is the slower axis
    assert frame.timing.move_s == pytest.approx(expected_move)
    assert frame.snapshot.turntable_deg == pytest.approx(90.0)
    assert frame.snapshot.arc_deg == pytest.approx(30.0)
    spent = clock.now()
    assert spent == pytest.approx(frame.timing.total_s if timed else 0.0)


def test_close_is_idempotent_and_final():
    sim = Simulator(small_scene("flat"))
    sim.render_state("cam0")
    sim.close()
    sim.close()
    with pytest.raises(RuntimeError, match="closed"):
        sim.render_state("cam0", turntable_deg=5.0)
