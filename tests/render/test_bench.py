"""``rig bench render`` rows, on a small frame so the test stays quick."""

import math
import os

import pytest

from render.bench import run_bench


@pytest.fixture(scope="module")
def bench_rows():
    return run_bench(quick=True, size=(64, 48))


def test_bench_rows_give_speed_as_a_ratio_to_the_plain_quad(bench_rows):
    rows = [r for r in bench_rows if r["kind"] == "pca"]
    assert [(r["components"], r["view_slots"]) for r in rows] == [(4, 1), (4, 4), (16, 1), (16, 4)]
    for row in rows:
        assert row["size"] == "64x48"
        assert row["fps"] > 0 and math.isfinite(row["fps"])
        assert math.isclose(row["ratio_to_plain"], row["fps"] / row["plain_fps"], rel_tol=0.01)
        threads = (os.cpu_count() or 1) + 1  # llvmpipe's rasteriser threads and ours
        assert row["plain_cpu_ms"] > 0 and 0 < row["cpu_ms"] <= threads * 1000 / row["fps"]


def test_mdf_shadow_rows_are_ratios_to_the_frame_without_shadows(bench_rows):
    rows = [r for r in bench_rows if r["kind"] == "mdf shadows"]
    assert [(r["shadows"], r["mdf"]) for r in rows] == [("off", "off"), ("on", "off"), ("on", "on")]
    assert rows[0]["ratio_to_btf_only"] == 1.0
    for row in rows:
        assert row["fps"] > 0 and math.isfinite(row["fps"])
        assert math.isclose(row["ratio_to_btf_only"], row["fps"] / rows[0]["fps"], rel_tol=0.01)
