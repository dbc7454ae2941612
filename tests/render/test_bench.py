"""``rig bench render`` rows, on a small frame so the test stays quick."""

import math
import os

from render.bench import run_bench


def test_bench_rows_give_speed_as_a_ratio_to_the_plain_quad():
    rows = run_bench(quick=True, size=(64, 48))
    assert [(r["components"], r["view_slots"]) for r in rows] == [(4, 1), (4, 4), (16, 1), (16, 4)]
    for row in rows:
        assert row["size"] == "64x48"
        assert row["fps"] > 0 and math.isfinite(row["fps"])
        assert math.isclose(row["ratio_to_plain"], row["fps"] / row["plain_fps"], rel_tol=0.01)
        threads = (os.cpu_count() or 1) + 1  # llvmpipe's rasteriser threads and ours
        assert row["plain_cpu_ms"] > 0 and 0 < row["cpu_ms"] <= threads * 1000 / row["fps"]
