"""Simulator API: frames, timing, life cycle, memory."""

import dataclasses
import json
import subprocess
import sys
import tracemalloc

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


def _hit_inputs(sim, camera_id="cam0"):
    """What ``Simulator`` hands ``SceneModel.hits`` for one frame (no supersampling)."""
    camera = sim.model.camera(camera_id)
    faces = sim._raster.face_ids(camera, 0.0)
    origin, dirs = sim.model.camera_rays(camera, 0.0)
    pixels = np.flatnonzero(faces.ravel() >= 0)
    return faces.shape, pixels, origin, dirs[pixels], faces.ravel()[pixels]


def test_hits_built_in_chunks_are_the_same_and_bound_the_temporaries(bumps_sim):
    inputs = _hit_inputs(bumps_sim)
    whole = bumps_sim.model.hits(*inputs, chunk=len(inputs[1]))
    tracemalloc.start()
    try:
        chunked = bumps_sim.model.hits(*inputs, chunk=len(inputs[1]) // 16)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    for field in dataclasses.fields(whole):
        np.testing.assert_array_equal(getattr(chunked, field.name), getattr(whole, field.name))
    # the parts and their concatenation, plus one chunk's temporaries (whole: ~3×)
    assert peak < 2.3 * whole.nbytes, (peak, whole.nbytes)


def test_the_hits_cache_holds_at_most_its_bytes(monkeypatch):
    sim = Simulator(small_scene("bumps", params={"grid": 65}))
    try:
        one = sim.model.hits(*_hit_inputs(sim)).nbytes
        monkeypatch.setattr(sim._hits, "max_bytes", int(2.5 * one))
        for camera_id in ("cam0", "cam1", "cam2", "cam3"):
            sim.render_state(camera_id, lamps_on=["lamp1"])
        assert len(sim._hits) == 2
        assert sum(hits.nbytes for hits in sim._hits.values()) <= 2.5 * one
    finally:
        sim.close()


_COMPILED = """
import json
from sim import Simulator, raycast, sensor, shading
from tests.sim.frame_sequence import sequence_scene

passes = (shading._exact_hits, shading._point_irradiance, raycast._shadow_rays,
          sensor._ziggurat, sensor._gaussian_dn)
with Simulator(sequence_scene()) as sim:
    built = [len(p.signatures) for p in passes]
    sim.render_state("cam2", turntable_deg=37.5, lamps_on=["lamp1"])
    print(json.dumps([built, [len(p.signatures) for p in passes]]))
"""


def test_a_new_simulator_has_its_compiled_passes_before_the_first_frame():
    """A camera server's first capture must not wait for numba (seconds, past its
    timeout): the passes a frame runs are compiled, for a frame's own types, when the
    simulator is made (in a fresh process: this one may have compiled them already)."""
    reply = subprocess.run([sys.executable, "-c", _COMPILED], capture_output=True, text=True,
                           check=True)  # fmt: skip
    built, after_frame = json.loads(reply.stdout.strip().splitlines()[-1])
    assert all(n >= 1 for n in built) and after_frame == built
