"""``rig bench process``: rows per size and worker count, items counted against the work done."""

import pytest
from typer.testing import CliRunner

from orchestrator.cli import app
from studies.process_scaling import run

# Sessions, subprocesses or benches: the full tier only (make test), not make quick.
pytestmark = pytest.mark.slow


def test_rows_count_the_views_processed_and_speedup_is_against_one_worker():
    rows = run(sizes=(32,), workers=(2, 1), clusters=("threads",), views=3, lamps=3, repeats=1)
    assert [(r["cluster"], r["size"], r["workers"]) for r in rows] == [
        ("threads", 32, 1),
        ("threads", 32, 2),
    ]
    for row in rows:
        # items: what the runner planned and computed; written: views found in material/ps
        assert row["items"] == row["written"] == 3
        assert 0 < row["compute_share"] <= 1
        assert row["cpu_s_per_item"] > 0 and row["cpu_per_compute"] > 0
    assert rows[0]["speedup"] == 1.0  # the one-worker row is the baseline of the others


def test_an_unknown_cluster_kind_is_named_with_the_valid_ones():
    with pytest.raises(ValueError, match=r"\['fibers'\].*threads.*processes"):
        run(clusters=("threads", "fibers"))


def test_help_says_what_is_measured():
    result = CliRunner().invoke(app, ["bench", "process", "--help"])
    assert result.exit_code == 0
    assert "workers" in result.output and "--size" in result.output
