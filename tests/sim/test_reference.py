"""Interreflection from Mitsuba 3: its direct light agrees with ours, indirect adds."""

import numpy as np
import pytest

from sim import Simulator
from tests.sim.sim_scenes import small_scene

mi = pytest.importorskip("mitsuba", reason="install btfrig[reference] for interreflection")


def test_mitsuba_direct_matches_and_indirect_is_small_and_positive():
    from sim.reference import MitsubaReference

    scene = small_scene("bumps", effects=["interreflection"], scale=0.0625,
                        params={"grid": 33}, interreflection={"samples_per_pixel": 8})  # fmt: skip
    with Simulator(scene) as sim:
        snap = sim.render_state("cam3", turntable_deg=30.0, lamps_on=["lamp3"]).snapshot
        ref = MitsubaReference(sim.model, scene.spec.params("interreflection"))
        theirs = np.array(mi.render(ref._scene("cam3", snap, 2), seed=1))
        ours = sim.image_truth("cam3", snap) / (0.05 / 0.5 * 255)
        # Same camera, lamp and geometry: direct light agrees up to MC noise and
        # the per-vertex albedo Mitsuba gets (markers averaged).
        assert np.mean(np.abs(theirs - ours)) < 0.1 * ours.max()
        frame = sim.render_state("cam3", turntable_deg=30.0, lamps_on=["lamp3"])
        extra = frame.signal - sim.image_truth("cam3", snap)
        assert np.percentile(extra, 1) > -1e-3  # only silhouettes differ downwards
        assert 0 < extra.mean() < 0.2 * frame.signal.mean()
        assert sim.counters["stage.interreflection"] == 2  # one per frame
