"""Configs and archives of every rig kind written before rig kinds became modules still load
(tests/data/stored_kinds, README there), and today's kinds answer for them."""

from __future__ import annotations

from pathlib import Path

import pytest

from rig.archive import Archive
from rig.config import RigConfig, load_rig_config, write_rig_config
from rig.kinds import rig_kind
from rig.plan import parse_plan
from rig.schedule import compile_plan

STORED = Path(__file__).resolve().parents[1] / "data" / "stored_kinds"
KINDS = ("wang", "bonn", "virtex")
PS = '[sample]\nname = "s"\n[captures.ps]\nlights = {theta_deg = 45, count = 3}\n'


@pytest.mark.parametrize("kind", KINDS)
def test_a_stored_config_loads_as_its_kind_and_writes_back_the_same(kind, tmp_path):
    config = load_rig_config(STORED / f"{kind}.toml")
    assert config.kind == kind and rig_kind(config).name == kind
    again = write_rig_config(config, tmp_path / "again.toml")
    assert again.read_text() == (STORED / f"{kind}.toml").read_text()


@pytest.mark.parametrize("kind", KINDS)
def test_a_stored_archive_opens_and_its_steps_read_back_through_the_kind(kind):
    with Archive.open(STORED / f"{kind}.zarr") as archive:
        config = RigConfig.model_validate(archive.rig_config)
        steps = archive.step_table()
        frames = [archive.read_frame(s.index, c, 0) for s in steps for c in s.cameras]
    assert config.kind == kind and steps and all(f.size for f in frames)
    rig = rig_kind(config)
    for step in steps:
        assert rig.displaced_by_deg(config, step.actuators) >= 0.0
        assert rig.recorded_lamp_mm(config, step.lamp, step.actuators).shape == (3,)


def test_a_plan_compiles_on_every_stored_kind_that_can_take_it():
    compiled = {
        kind: compile_plan(parse_plan(PS), load_rig_config(STORED / f"{kind}.toml"))
        for kind in KINDS
    }
    assert {kind: len(s.steps) for kind, s in compiled.items()} == {
        "wang": 3, "bonn": 3, "virtex": 3,
    }  # fmt: skip
