from pathlib import Path

import pytest

from rig.errors import PlanError
from rig.plan import load_plan, parse_plan

EXAMPLES = sorted((Path(__file__).parents[2] / "examples" / "plans").glob("*.toml"))


@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: p.name)
def test_example_plans_are_valid(path):
    plan = load_plan(path)
    assert plan.sample.name


def test_minimal_plan_defaults():
    plan = parse_plan('[sample]\nname = "x"\n[captures.ps]\nlights = {theta_deg = 45, count = 3}')
    assert plan.captures.ps.views.resolve().directions.tolist() == [[0.0, 0.0]]
    lights = plan.captures.ps.lights.resolve().directions
    assert lights[:, 1].tolist() == [0.0, 120.0, 240.0]  # seed 004: 120° apart
    assert plan.archive_path() == Path("sessions/x.zarr")


def _problems(text):
    with pytest.raises(PlanError) as info:
        parse_plan(text, source="p.toml")
    return info.value.problems


def test_every_problem_reported_once_with_field_and_fix():
    problems = _problems(
        """
[sample]
name = "a b"
colour = "red"
[captures.btf]
views = "H9"
lights = [[91, 0]]
[captures.ps]
lights = [[10, 0], [20, 0]]
[exposure]
exposure_s = 0
hdr_brackets = [1, 1]
[output]
archive = 3
"""
    )
    text = "\n".join(problems)
    assert len(problems) == 8, text
    assert "sample.name" in text and "letters, digits" in text
    assert "sample.colour: unknown field; valid fields here are ['description', 'name']" in text
    assert "captures.btf.views" in text and "'H1', 'H2'" in text
    assert "captures.btf.lights" in text and "0 ≤ theta ≤ 90" in text
    assert "captures.ps.lights" in text and "at least 3 lights" in text
    assert "exposure.exposure_s" in text and "greater than 0" in text
    assert "exposure.hdr_brackets" in text and "distinct" in text
    assert "output.archive" in text


def test_empty_plan_and_bad_toml():
    assert any("must capture something" in p for p in _problems('[sample]\nname="x"\n[captures]'))
    assert any("not valid TOML" in p for p in _problems("[sample\n"))
    with pytest.raises(PlanError, match="does not exist"):
        load_plan("/nonexistent/plan.toml")
