"""`rig run` in one process, and the daemon benchmark's shape (speed is not asserted here)."""

import pytest

from orchestrator.local import run_local
from rig.archive import Archive
from studies.daemon_overhead import run
from tests.orchestrator.daemon.conftest import TINY_PLAN
from tests.orchestrator.daemon.soft import soft_devices


def test_run_local_runs_a_whole_session(rig, tmp_path):
    plan = tmp_path / "plan.toml"
    plan.write_text(TINY_PLAN)
    events = []
    final = run_local(
        plan, None, archive=tmp_path / "r.zarr", workers=1, on_event=events.append,
        devices=soft_devices(rig), clock=rig.clock,
    )  # fmt: skip
    assert final["state"] == "done" and final["stream"]["processed"] == final["session"]["frames"]
    assert any(e["topic"] == "progress" for e in events)
    with Archive.open(tmp_path / "r.zarr") as archive:
        assert len(archive.committed_steps()) == final["session"]["steps"]


def test_bench_rows(benchmark):
    rows = benchmark.pedantic(run, kwargs={"quick": True}, rounds=1, iterations=1)
    assert [r["workers"] for r in rows] == [0, 2]
    for row in rows:
        assert row["frames"] > 0 and row["modelled_s"] > 0
        assert row["overhead_fraction"] > 0 and row["frames_per_s"] > 0
        # the modelled rig spends the estimate's time: one timing model for both
        assert row["modelled_s"] == pytest.approx(row["estimate_s"], rel=1e-9)
    assert rows[1]["processed"] == rows[1]["frames"]
