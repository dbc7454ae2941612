"""`rig plan --steps` lists each rig kind's steps with the pose its kind gives them."""

from __future__ import annotations

from pathlib import Path

import pytest
from typer.testing import CliRunner

from orchestrator.cli import app

STORED = Path(__file__).resolve().parents[1] / "data" / "stored_kinds"
PLAN = '[sample]\nname = "s"\n[captures.btf]\nviews = [[0, 0]]\nlights = [[34, 90]]\n'


@pytest.mark.parametrize(
    ("kind", "pose"), [("wang", "turntable 0.0°"), ("bonn", "rail 34.0°")]
)
def test_the_steps_table_shows_each_kinds_pose(kind, pose, tmp_path):
    (tmp_path / "plan.toml").write_text(PLAN)
    args = ["plan", str(tmp_path / "plan.toml"), "--config", str(STORED / f"{kind}.toml"),
            "--steps", "1"]  # fmt: skip
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.output
    said = " ".join(result.output.split())  # whatever the terminal's width
    assert pose in said and "Traceback" not in said
