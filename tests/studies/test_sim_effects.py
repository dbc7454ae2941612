"""The sim benchmark: each effect's time against the Lambertian baseline measured with it."""

import itertools

import pytest

import studies.sim_effects
from sim.simulator import Simulator
from studies.sim_effects import run

# Sessions, subprocesses or benches: the full tier only (make test), not make quick.
pytestmark = pytest.mark.slow

EFFECTS = ("shadows", "noise")


def test_ratios_are_each_case_over_its_interleaved_baseline(monkeypatch):
    """Renders of known cost: 10 ms a new view + 20 ms per effect; 2 ms + 1 ms per effect
    to re-light a cached view. The bench must recover exactly these ratios."""
    ticks = itertools.count()
    now = {"s": 0.0}

    def render_state(self, camera_id, *, turntable_deg, lamps_on, **_):
        effects = sum(self.scene.has(e) for e in EFFECTS)
        new_view = turntable_deg != 0.0
        cost_ms = 10 + 20 * effects if new_view else 2 + effects
        if next(ticks) == 0:
            cost_ms += 500  # a cold first frame, which the bench must leave out
        now["s"] += cost_ms / 1000

    monkeypatch.setattr(studies.sim_effects, "perf_counter", lambda: now["s"])
    monkeypatch.setattr(Simulator, "render_state", render_state)
    rows = run(sizes=(32,), effects=EFFECTS, runs=3)
    got = {r["effects"]: r for r in rows}
    assert list(got) == ["lambert (baseline)", "shadows", "noise", "shadows+noise"]
    expected = {  # effects: (frame_ms, relit_ms)
        "lambert (baseline)": (10, 2),
        "shadows": (30, 3),
        "noise": (30, 3),
        "shadows+noise": (50, 4),
    }
    for name, (frame_ms, relit_ms) in expected.items():
        row = got[name]
        assert row["frame_ms"] == pytest.approx(frame_ms)
        assert row["relit_ms"] == pytest.approx(relit_ms)
        assert row["ratio"] == pytest.approx(frame_ms / 10)
        assert row["relit_ratio"] == pytest.approx(relit_ms / 2)


def test_run_renders_real_frames():
    rows = run(sizes=(64,), effects=("shadows",), runs=1)
    assert [r["effects"] for r in rows] == ["lambert (baseline)", "shadows"]
    assert all(r["frame_ms"] > 0 and r["relit_ms"] > 0 for r in rows)
