from pathlib import Path

import pytest
from typer.testing import CliRunner

from rig.cli import app

EXAMPLES = Path(__file__).parents[2] / "examples" / "plans"
runner = CliRunner()


def test_every_command_has_help():
    result = runner.invoke(app, ["--help"])
    assert result.exit_code == 0
    for name in (
        "daemon",
        "submit",
        "status",
        "pause",
        "resume",
        "abort",
        "shutdown",
        "run",
        "plan",
        "worker",
        "process",
        "replay",
        "calibrate",
        "sim",
        "bench",
        "view",
    ):
        assert name in result.output
        sub = runner.invoke(app, [name, "--help"])
        assert sub.exit_code == 0, (name, sub.output)


def test_plan_estimate_prints_duration_and_size():
    result = runner.invoke(app, ["plan", str(EXAMPLES / "demo.toml"), "--estimate", "--steps", "3"])
    assert result.exit_code == 0, result.output
    assert "expected duration" in result.output
    assert "data size" in result.output
    assert "motion order saves" in result.output


def test_bad_plan_exits_2_with_field_names(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text('[sample]\nname = "x"\n[captures.btf]\nviews = "H7"\nlights = "H2"\n')
    result = runner.invoke(app, ["plan", str(bad)])
    assert result.exit_code == 2
    assert "captures.btf.views" in result.output


@pytest.mark.parametrize("args", [["replay", "s.zarr"], ["view", "m.zarr"], ["process", "s.zarr"]])
def test_unbuilt_commands_say_so_and_fail(args):
    result = runner.invoke(app, args)
    assert result.exit_code == 3
    assert "not built yet" in result.output


def test_status_without_a_daemon_fails_clearly():
    result = runner.invoke(app, ["status", "--connect", "tcp://127.0.0.1:1"])
    assert result.exit_code == 1
    assert "error" in result.output
