"""``rig bench mdf`` rows, and a pytest-benchmark of the space-time tracker."""

import numpy as np
import pytest

from processing.mdf import PEAK_METHODS, SpaceTimeTracker
from rig.config import default_rig_config
from studies.mdf_cost import capture_time_s, run

# Sessions, subprocesses or benches: the full tier only (make test), not make quick.
pytestmark = pytest.mark.slow


def test_capture_time_from_the_rig_config():
    config = default_rig_config()
    step = config.laser.sweep_speed_deg_s / config.laser.frame_rate_hz
    one = capture_time_s(config, locations=1, step_deg=step)
    # 12° sweep at 0.1333°/frame: 91 frames at 7.5 Hz.
    assert one == pytest.approx(91 / 7.5)
    five = capture_time_s(config, locations=5, step_deg=step)
    assert five > 5 * one  # plus four arc moves
    assert capture_time_s(config, locations=1, step_deg=step / 2) > 1.9 * one


def test_quick_bench_rows():
    rows = run(quick=True)
    kinds = [r["kind"] for r in rows]
    assert kinds.count("read") == 2
    tracked = [r for r in rows if r["kind"] == "space_time"]
    assert all(r["ratio_to_read"] > 0 and r["speedup_vs_argmax"] > 0 for r in tracked)
    for r in tracked:  # best-of parts add up to at most the best-of whole
        parts = r["streaming_ratio_to_read"] + r["fit_ratio_to_read"]
        assert 0 < parts <= r["ratio_to_read"] * 1.001
    assert {r["name"] for r in tracked} == {
        f"{method}, 24 frames {feed}"
        for method in PEAK_METHODS
        for feed in ("one at a time", "stacked")
    }
    assert kinds.count("detector") == len(PEAK_METHODS)
    accuracy = [r for r in rows if r["kind"] == "accuracy"]
    assert {(r["locations"], round(r["step_deg"], 4)) for r in accuracy} == {
        (1, 0.1333),
        (5, 0.1333),
        (1, 0.2667),
        (5, 0.2667),
    }
    for r in rows:
        for key, value in r.items():
            if isinstance(value, float):
                assert np.isfinite(value), (r, key)
    for r in accuracy:
        assert 0 <= r["coverage"] <= 1 and r["capture_time_s"] > 0
    five = [r for r in accuracy if r["locations"] == 5]
    assert all(r["coverage"] > 0.99 for r in five)
    assert all(0 <= r["line_error_px"] < 0.2 for r in rows if r["kind"] == "detector")


def test_tracker_benchmark(benchmark):
    rng = np.random.default_rng(0)
    frames = [rng.integers(0, 255, (192, 256), dtype=np.uint8) for _ in range(20)]

    def run():
        tracker = SpaceTimeTracker((192, 256), min_contrast=20.0)
        for f in frames:
            tracker.update(f)
        return tracker.result()

    peaks = benchmark(run)
    assert peaks.frames == 20
