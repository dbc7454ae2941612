"""An effect the scene does not list costs nothing: count passes and stages."""

from sim import Simulator
from tests.sim.sim_scenes import small_scene

EFFECT_STAGES = {
    "shadows", "specular", "laser", "noise", "saturation", "vignetting", "lens_distortion",
}  # fmt: skip


def _stages(counters):
    return {k.removeprefix("stage.") for k in counters if k.startswith("stage.")}


def test_no_effects_only_lambert_and_one_gl_pass_per_view():
    with Simulator(small_scene("bumps", params={"grid": 33})) as sim:
        for lamp in ("lamp0", "lamp2", "lamp5"):
            sim.render_state("cam2", lamps_on=[lamp], laser=True)
        assert sim.counters["gl_pass"] == 1  # ids reused across lamps
        assert _stages(sim.counters) == {"lambert"}
        assert sim.counters["raycast.shadows"] == 0
        assert sim.model.caster.rays == 0  # nothing ray-cast at all
        sim.render_state("cam2", turntable_deg=10.0, lamps_on=["lamp0"])
        assert sim.counters["gl_pass"] == 2  # a new turntable angle is a new view


def test_each_listed_effect_runs_once_per_frame():
    effects = sorted(EFFECT_STAGES)
    scene = small_scene("bumps", effects=effects, params={"grid": 33},
                        materials={"default": {"specular": {"model": "phong"}}})  # fmt: skip
    with Simulator(scene) as sim:
        sim.render_state("cam2", lamps_on=["lamp3"], laser=True)
        assert _stages(sim.counters) == EFFECT_STAGES | {"lambert"}
        assert all(sim.counters[f"stage.{e}"] == 1 for e in EFFECT_STAGES)
        # The shadow rays for a (view, lamp) are cached: a second frame casts none.
        sim.render_state("cam2", lamps_on=["lamp3"])
        assert sim.counters["raycast.shadows"] == 1
