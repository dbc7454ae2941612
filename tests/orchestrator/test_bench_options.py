"""`rig bench`'s selections: a loop study runs only the samples, plans, processings and
runs asked for, and a bad one is exit 2 naming what would be valid."""

import json

import pytest
from typer.testing import CliRunner

from orchestrator.cli import app

runner = CliRunner()


def _run(*args):
    result = runner.invoke(app, ["bench", *map(str, args)])
    assert "Traceback" not in result.output, result.output
    return result


def test_one_sample_plan_run_and_processing_are_all_that_is_measured(tmp_path):
    out = tmp_path / "rows.json"
    result = _run("error-budget", "--quick", "--sample", "bumps", "--plan", "coarse",
                  "--run", "none", "--processing", "raw", "--json", out)  # fmt: skip
    assert result.exit_code == 0, result.output
    rows = json.loads(out.read_text())
    assert [(r["scene"], r["plan"], r["run"], r["processing"], r["components"]) for r in rows] == [
        ("bumps", "coarse", "all terms on", "raw", 4),
        ("bumps", "coarse", "all terms on", "raw", "lossless"),
    ]
    assert rows[0]["render_scale"] == 0.5


@pytest.mark.parametrize(
    ("args", "named"),
    [
        (("error-budget", "--sample", "cloth"), "--sample: 'cloth': valid are bumps, weave"),
        (("render-loop", "--plan", "H2"), "--plan: 'H2': valid are coarse, medium, fine, H1"),
        (("lab-loop", "--plan", "dense"), "--plan: 'dense': valid are coarse, medium, fine, H1"),
        (("error-budget", "--run", "noise,glare"), "--run: 'glare': valid are noise, near-lamps"),
        (("error-budget", "--processing", "flat field"), "'flat field': valid are raw, irradiance"),
        (("error-budget", "--render-scale", "0"), "--render-scale: 0: valid is 0 < scale ≤ 4"),
        (("error-budget", "--render-scale", "4.5"), "--render-scale: 4.5: valid is 0 < scale ≤ 4"),
    ],
)
def test_a_bad_selection_is_named_with_the_valid_ones_before_anything_runs(args, named):
    result = _run(*args)
    assert result.exit_code == 2, result.output
    assert named in " ".join(result.output.split())
    assert "measuring" not in result.output


def test_hyphens_read_as_spaces_and_runs_name_their_terms():
    from orchestrator.cli.bench_cmd import _selected
    from studies import error_budget

    assert _selected(error_budget, "processings", ["lights-per-texel", "Raw"]) == (
        "lights per texel", "raw",
    )  # fmt: skip
    assert _selected(error_budget, "runs", ["none", "near-lamps,perspective", "all"]) == (
        (), ("near lamps", "perspective"), tuple(error_budget.TERMS),
    )  # fmt: skip
    assert _selected(error_budget, "plans", ["h1"]) == ("H1",)


def test_each_options_help_names_every_value_its_study_takes():
    from orchestrator.cli.bench_cmd import SELECTIONS
    from studies import error_budget

    for name, (_, _, text, table) in SELECTIONS.items():
        if name == "render_scale":
            assert f"≤ {error_budget.MAX_RENDER_SCALE:g}" in text
            continue
        for value in getattr(error_budget, table):
            assert value.replace(" ", "-") in text, (name, value)
