"""The registry of studies and `rig bench`: one command per study, one way to run it."""

import inspect
import json
from types import SimpleNamespace

import pytest
from typer.testing import CliRunner

from orchestrator.cli import app
from studies import STUDIES, Study, study

runner = CliRunner()


@pytest.mark.parametrize("entry", STUDIES, ids=lambda s: s.name)
def test_each_study_runs_by_quick_alone_and_plots_where_it_says(entry):
    module = entry.load()
    parameters = list(inspect.signature(module.run).parameters.values())
    assert parameters[0].name == "quick"
    # everything after quick has a default: `run(quick)` is the whole call
    assert all(p.default is not p.empty for p in parameters[1:]), parameters
    assert hasattr(module, "plot") == entry.figure


def test_names_and_modules_are_unique():
    assert len({s.name for s in STUDIES}) == len({s.module for s in STUDIES}) == len(STUDIES)


def test_an_unknown_study_names_the_valid_ones():
    with pytest.raises(KeyError, match="no study 'nope': valid are archive, daemon"):
        study("nope")


def test_rig_bench_help_lists_every_study_with_its_line():
    result = runner.invoke(app, ["bench", "--help"], env={"COLUMNS": "80"})
    assert result.exit_code == 0, result.output
    lines = result.output.splitlines()
    listed = dict(line.split(maxsplit=1) for line in lines[lines.index("Commands:") + 1 :])
    assert listed == {s.name: s.summary for s in STUDIES}


@pytest.mark.parametrize("entry", STUDIES, ids=lambda s: s.name)
def test_each_study_says_what_it_measures(entry):
    result = runner.invoke(app, ["bench", entry.name, "--help"], env={"COLUMNS": "80"})
    lines = result.output.splitlines()
    description = "".join(lines[lines.index("") + 1 : lines.index("Options:")])
    # the same words, wherever the help wrapped them
    assert "".join(description.split()) == "".join(entry.description.split())
    assert ("--plot" in result.output) == entry.figure


def test_a_study_runs_its_quick_rows_into_json_markdown_and_its_plot(monkeypatch, tmp_path):
    calls = []
    rows = [{"components": 4, "psnr_db": 31.25}]
    fake = SimpleNamespace(
        run=lambda quick: calls.append(("run", quick)) or rows,
        plot=lambda got, path: calls.append(("plot", got, path)),
    )
    monkeypatch.setattr(Study, "load", lambda self: fake)
    out = tmp_path / "rows.json"
    args = ["bench", "btf", "--quick", "--json", str(out), "--markdown", str(tmp_path / "t.md"),
            "--plot", str(tmp_path / "f.png")]  # fmt: skip
    result = runner.invoke(app, args)
    assert result.exit_code == 0, result.output
    assert calls == [("run", True), ("plot", rows, tmp_path / "f.png")]
    assert json.loads(out.read_text()) == rows
    assert "| 4 | 31.25 |" in (tmp_path / "t.md").read_text()
