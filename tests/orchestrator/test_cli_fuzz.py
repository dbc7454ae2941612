"""Plan files a careless user or an adversary might write: random TOML, and the
example plan with random edits. `rig plan` reads each and either accepts it or
names its problems (exit 2); it never fails in another way."""

from __future__ import annotations

import tomllib
from pathlib import Path

import pytest
import tomli_w
from hypothesis import event, given
from hypothesis import strategies as st
from typer.testing import CliRunner

from orchestrator.cli import app
from rig.errors import PlanError
from rig.plan import Plan, load_plan
from tests.budgets import fuzz

DEMO = (Path(__file__).parents[2] / "examples" / "plans" / "demo.toml").read_bytes()

# the plan's own field names, so random tables often reach deep validation
KEYS = st.sampled_from(
    ("sample", "name", "description", "captures", "btf", "ps", "mdf", "fixed", "views",
     "lights", "laser_locations", "scan_step_deg", "named", "directions", "ring", "theta_deg",
     "count", "phi0_deg", "turntable_deg", "arc_deg", "lamp", "cameras", "exposure",
     "exposure_s", "hdr_brackets", "laser_exposure_s", "gain_db", "resolution", "scale",
     "output", "archive", "H1", "H2")
)  # fmt: skip
SCALARS = st.one_of(
    st.integers(-(2**63), 2**63 - 1),
    st.floats(),  # nan and ±inf included
    st.text(max_size=12),
    st.sampled_from(["H1", "H2", "{sample}", "{x}", "out/{sample}.zarr", "cam0", "lamp0"]),
    st.booleans(),
)
VALUES = st.recursive(
    SCALARS,
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(KEYS, inner, max_size=4),
    max_leaves=24,
)
RANDOM_TOML = st.dictionaries(KEYS, VALUES, max_size=6).map(lambda d: tomli_w.dumps(d).encode())
EDITS = st.lists(
    st.tuples(
        st.floats(0, 1),
        st.integers(0, 6),  # bytes removed
        st.binary(max_size=6)
        | st.sampled_from([b"[", b"]]", b"{", b"}", b"=", b'"', b"\n", b"-1", b"1e999", b"nan"]),
    ),
    min_size=1,
    max_size=6,
)


def _edited(edits) -> bytes:
    text = bytearray(DEMO)
    for where, removed, inserted in edits:
        at = round(where * len(text))
        text[at : at + removed] = inserted
    return bytes(text)


def _leaves(table: dict, prefix=()):
    for key, value in table.items():
        yield from _leaves(value, (*prefix, key)) if isinstance(value, dict) else [(*prefix, key)]


def _replaced(where_value) -> bytes:
    *parents, leaf = where_value[0]
    plan = tomllib.loads(DEMO.decode())
    table = plan
    for key in parents:
        table = table[key]
    table[leaf] = where_value[1]
    return tomli_w.dumps(plan).encode()


# the example plan with one value replaced: often valid, so compiling paths are reached too
PLAUSIBLE = st.one_of(
    st.integers(0, 90),
    st.floats(0, 90),
    st.lists(st.tuples(st.floats(0, 89), st.floats(-360, 360)).map(list), max_size=4),
    st.fixed_dictionaries({"theta_deg": st.floats(0, 89), "count": st.integers(1, 12)}),
)
REPLACED = st.tuples(
    st.sampled_from(list(_leaves(tomllib.loads(DEMO.decode())))), PLAUSIBLE | VALUES
)
PLAN_FILES = RANDOM_TOML | EDITS.map(_edited) | REPLACED.map(_replaced)


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    return tmp_path_factory.mktemp("plans")


@fuzz()
@given(content=PLAN_FILES)
def test_a_plan_file_is_accepted_or_its_problems_named(folder, content):
    path = folder / "plan.toml"
    path.write_bytes(content)
    try:
        plan = load_plan(path)
    except PlanError as err:
        problem = err
    else:
        event("valid")
        assert isinstance(plan, Plan)
        assert plan.archive_path().name  # the archive's name can be formed
        return
    event("invalid")
    assert str(problem).startswith(f"{path}: ") and problem.problems
    assert all(line.strip() for line in problem.problems)


runner = CliRunner()


@given(content=PLAN_FILES)
def test_rig_plan_exits_0_or_2_with_one_message(folder, content):
    path = folder / "cli.toml"
    path.write_bytes(content)
    result = runner.invoke(app, ["plan", str(path)])
    assert "Traceback" not in result.output
    if result.exit_code == 0:
        assert "is valid" in result.output
    else:
        assert result.exit_code == 2, result.output
        assert result.output.startswith(f"error: {path}: "), result.output
