"""The benchmark entry point runs and reports what it promises (timings not asserted)."""

import numpy as np
import pytest

from processing.photometric import DistantLights, solve
from studies.ps_cost import lamp_layout, run

# Sessions, subprocesses or benches: the full tier only (make test), not make quick.
pytestmark = pytest.mark.slow


def test_run_rows_on_a_small_stack():
    rows = run(
        n_lights=12,
        size_px=64,
        robust_rows=16,
        accuracy_px=32,
        lamp_counts=(3, 6, None),
        repeats=1,
        capture_time_s=lambda n: 2.5 * n,
    )
    kinds = {r["kind"] for r in rows}
    assert kinds == {"read", "solver", "integrator", "accuracy"}
    solvers = {r["name"]: r for r in rows if r["kind"] == "solver"}
    assert set(solvers) == {"lsq", "lsq, 5% mask", "threshold", "irls", "near lsq"}
    assert solvers["lsq"]["ratio_to_astype_sum"] > 0
    assert solvers["lsq"]["ratio_to_gemm"] > 0 and solvers["irls"]["ratio_to_gemm"] > 0
    assert solvers["lsq, 5% mask"]["ratio_to_packed"] > 0
    accuracy = [r for r in rows if r["kind"] == "accuracy"]
    assert sorted({r["n_lamps"] for r in accuracy}) == [3, 6, 12]
    assert len(accuracy) == 3 * 2 * 3  # lamp counts × scenarios × methods
    assert all(r["capture_time_s"] == 2.5 * r["n_lamps"] for r in accuracy)
    assert all(np.isfinite(r["seconds_per_mpx"]) for r in rows if "seconds_per_mpx" in r)


def test_lamp_layout_is_unit_and_well_conditioned():
    for n in (3, 4, 5, 6, 12, 96):
        dirs = lamp_layout(n)
        assert dirs.shape == (n, 3)
        np.testing.assert_allclose(np.linalg.norm(dirs, axis=1), 1.0)
        assert np.linalg.cond(dirs) < 10


def test_lsq_benchmark(benchmark):
    rng = np.random.default_rng(0)
    stack = rng.random((24, 128, 128), dtype=np.float32)
    result = benchmark(solve, stack, DistantLights(lamp_layout(24)), method="lsq")
    assert result.valid.all()
