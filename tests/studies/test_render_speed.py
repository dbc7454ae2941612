"""``rig bench render`` rows, on a small frame so the test stays quick."""

import math
import os

import pytest

from studies.render_speed import run

# Sessions, subprocesses or benches: the full tier only (make test), not make quick.
pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def bench_rows():
    return run(quick=True, size=(64, 48))


def test_bench_rows_give_speed_as_a_ratio_to_the_plain_quad(bench_rows):
    rows = [row for row in bench_rows if row["kind"] == "pca"]
    assert [(r["components"], r["view_slots"]) for r in rows] == [(4, 1), (4, 4), (16, 1), (16, 4)]
    for row in rows:
        assert row["size"] == "64x48"
        assert row["fps"] > 0 and math.isfinite(row["fps"]) and row["ratio_to_plain"] > 0
        threads = (os.cpu_count() or 1) + 1  # llvmpipe's rasteriser threads and ours
        assert row["plain_cpu_ms"] > 0 and 0 < row["cpu_ms"] <= threads * 1000 / row["fps"]


def test_bench_rows_give_the_mdf_cost_as_a_ratio_to_the_btf_alone(bench_rows):
    rows = [row for row in bench_rows if row["kind"] == "mdf"]
    assert [(r["mdf"], r["peel"]) for r in rows] == [(False, 0), (True, 1), (True, 2), (True, 3)]
    assert rows[0]["ratio_to_btf"] == 1.0
    for row in rows:
        assert row["fps"] > 0 and math.isfinite(row["fps"])


def test_mdf_shadow_rows_are_ratios_to_the_frame_without_shadows(bench_rows):
    rows = [row for row in bench_rows if row["kind"] == "mdf shadows"]
    assert [(r["shadows"], r["mdf"]) for r in rows] == [(False, False), (True, False), (True, True)]
    assert rows[0]["ratio_to_btf"] == rows[0]["cpu_ratio_to_btf"] == 1.0
    for row in rows:
        assert row["fps"] > 0 and math.isfinite(row["fps"])
