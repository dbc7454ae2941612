"""The rasterised Lambertian frame equals the ray-cast ground-truth shading.

Tolerance: mean absolute difference < 0.5 % of white (full scale, 255 DN);
the two paths pick different triangles only on silhouettes.
"""

import numpy as np
import pytest

from sim import Simulator
from tests.sim.sim_scenes import small_scene

WHITE = 255.0


@pytest.mark.parametrize("generator", ["bumps", "weave", "knit"])
def test_lambertian_frame_matches_raycast_truth(generator):
    with Simulator(small_scene(generator)) as sim:
        for camera, tt, arc in (("cam0", 0.0, 0.0), ("cam3", 30.0, 70.0), ("cam5", 200.0, 10.0)):
            frame = sim.render_state(
                camera, turntable_deg=tt, arc_deg=arc, lamps_on=["lamp1", "lamp4"]
            )
            truth = sim.image_truth(camera, frame.snapshot)
            err = np.abs(frame.signal - truth)
            assert err.mean() < 0.005 * WHITE
            assert np.mean(err > 0.01) < 0.01  # only silhouette pixels differ
            assert truth.max() > 0.2 * WHITE  # a lit scene, not two black images


def test_shadowed_frame_matches_raycast_truth():
    scene = small_scene("bumps", effects=["shadows", "specular"], params={"amplitude_mm": 2.0},
                        materials={"default": {"specular": {"model": "phong"}}})  # fmt: skip
    with Simulator(scene) as sim:
        frame = sim.render_state("cam4", turntable_deg=45.0, lamps_on=["lamp5"])
        truth = sim.image_truth("cam4", frame.snapshot)
        assert np.abs(frame.signal - truth).mean() < 0.005 * WHITE
        lit = sim.truth("cam4", 45.0, lamps=["lamp5"]).lit["lamp5"]
        t = sim.truth("cam4", 45.0)
        shadowed = t.mask & ~lit
        assert shadowed.sum() > 20  # grazing lamp over 2 mm bumps casts shadows
        assert np.all(frame.signal[shadowed] < 1.0)


def test_lambert_radiance_is_exact_on_a_flat_sample():
    # L = ρ/π · I · cosθ / r² for a point lamp, checked at the centre pixel.
    scene = small_scene("flat", scale=0.125, sample={"generator": "flat", "depth_mm": 2.0})
    with Simulator(scene) as sim:
        frame = sim.render_state("cam0", lamps_on=["lamp0"])
        rig = scene.rig
        cam = rig.camera_model("cam0")
        h, w = frame.signal.shape[:2]
        _, dirs = cam.rays([[(w - 1) / 2, (h - 1) / 2]])
        point = cam.center + dirs[0] * (-2.0 - cam.center[2]) / dirs[0][2]
        lamp = np.array([0, 0, rig.light_arc.radius_mm])
        r = np.linalg.norm(lamp - point)
        cos_i = (lamp - point)[2] / r
        radiance = 0.7 / np.pi * 10.0 * cos_i / (r / 1000) ** 2
        expected = radiance * 0.05 / 0.5 * 255
        assert frame.signal[h // 2, w // 2, 0] == pytest.approx(expected, rel=2e-3)
