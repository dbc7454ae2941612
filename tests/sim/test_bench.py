"""The sim benchmark runs and reports a ratio against its own baseline."""

from sim.bench import run_bench


def test_run_bench_rows():
    rows = run_bench(sizes=(64,), effects=("shadows", "noise"), runs=1)
    assert [r["effects"] for r in rows] == [
        "lambert (baseline)", "shadows", "noise", "shadows+noise",
    ]  # fmt: skip
    assert 0.2 < rows[0]["ratio"] < 5  # baseline against itself
    assert all(r["frame_ms"] > 0 and r["relit_ms"] > 0 for r in rows)
