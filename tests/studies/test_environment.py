"""``rig bench environment`` rows (quick mode): error falls with the hemicube resolution."""

import math

import pytest

from studies.environment import run

# Sessions, subprocesses or benches: the full tier only (make test), not make quick.
pytestmark = pytest.mark.slow


def test_environment_bench_rows():
    rows = run(quick=True)
    vis = [r for r in rows if r["row"] == "visibility"]
    assert [r["vis_res"] for r in vis] == [2, 4, 8]
    assert vis[-1]["max_error"] < vis[0]["max_error"] / 4
    pca = [r for r in rows if r["row"] == "pca"]
    assert pca[-1]["error_at_sample"] < pca[0]["error_at_sample"]
    for row in rows:
        assert all(math.isfinite(v) for v in row.values() if isinstance(v, float))
    assert {r["vertices"] for r in rows if r["row"] == "vertices"} == {289, 625}
    cut = [r for r in rows if r["row"] == "median_cut"]
    assert [r["count"] for r in cut] == [4, 16] and cut[1]["max_error"] < cut[0]["max_error"]
    pem = [r for r in rows if r["row"] == "pem"]
    assert [r["count"] for r in pem] == [4, 16] and pem[1]["max_error"] < pem[0]["max_error"]
    assert all(r["max_error"] < r["max_error_point_lights"] for r in pem)
