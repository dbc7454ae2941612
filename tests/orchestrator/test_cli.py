import sys
from pathlib import Path

import pytest
from typer.testing import CliRunner

from orchestrator.cli import app

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


@pytest.mark.parametrize("args", [["export", "png16", "s.zarr", "--out", "x"]])
def test_unbuilt_commands_say_so_and_fail(args):
    result = runner.invoke(app, args)
    assert result.exit_code == 3
    assert "not built yet" in result.output


def test_status_without_a_daemon_fails_clearly():
    result = runner.invoke(app, ["status", "--connect", "tcp://127.0.0.1:1"])
    assert result.exit_code == 1
    assert "error" in result.output


def test_replay_of_a_missing_archive_names_it(tmp_path):
    result = runner.invoke(app, ["replay", str(tmp_path / "nowhere.zarr"), "--max"])
    assert result.exit_code == 1
    assert "nowhere.zarr" in result.output and "no archive here" in result.output


def test_run_refuses_both_config_and_sim(tmp_path):
    config = tmp_path / "rig.toml"
    config.write_text("")
    args = ["run", str(EXAMPLES / "demo.toml"), "--config", str(config)]
    result = runner.invoke(app, [*args, "--sim", "examples/scenes/bumps.toml"])
    assert result.exit_code == 2
    assert "--config and --sim" in result.output


@pytest.mark.parametrize(
    ("spec", "message"),
    [("cameras.dropped_frames", "expected PEER.KEY=VALUE"), ("cameras.x=[1,", "not a TOML value")],
)
def test_sim_serve_rejects_a_bad_fault(spec, message):
    result = runner.invoke(app, ["sim", "serve", "examples/scenes/bumps.toml", "--fault", spec])
    assert result.exit_code == 2
    assert message in result.output


def test_sim_serve_rejects_a_fault_for_an_unknown_peer(tmp_path):
    args = ["sim", "examples/scenes/bumps.toml", "--config-out", str(tmp_path / "c.toml")]
    result = runner.invoke(app, [*args, "--fault", "toaster.burn=true"])
    assert result.exit_code == 2
    assert "toaster" in result.output and "valid are" in result.output
    assert not (tmp_path / "c.toml").exists()


def test_parse_faults_reads_toml_values():
    from orchestrator.cli.sim_cmd import parse_faults

    faults = parse_faults(["cameras.dropped_frames=2", "lamp_bank.dead_lamps=['lamp3']"])
    assert faults == {"cameras": {"dropped_frames": 2}, "lamp_bank": {"dead_lamps": ["lamp3"]}}


def test_process_of_a_missing_archive_names_it(tmp_path):
    result = runner.invoke(app, ["process", str(tmp_path / "nowhere.zarr")])
    assert result.exit_code == 1
    assert "nowhere.zarr" in result.output and "no archive here" in result.output


def test_process_without_dask_names_the_extra(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)  # as if btfrig[dask] were not installed
    result = runner.invoke(app, ["process", str(tmp_path / "s.zarr")])
    assert result.exit_code == 1, result.output
    assert "btfrig[dask]" in result.output
    assert "Traceback" not in result.output


def test_sim_render_without_the_simulator_names_the_extra(tmp_path, monkeypatch):
    for name in [m for m in sys.modules if m == "sim" or m.startswith("sim.")]:
        monkeypatch.delitem(sys.modules, name)  # so the simulator is imported afresh
    monkeypatch.setitem(sys.modules, "trimesh", None)
    args = ["sim", "render", "examples/scenes/bumps.toml", "--out", str(tmp_path)]
    result = runner.invoke(app, args)
    assert result.exit_code == 1, result.output
    assert "btfrig[sim]" in result.output
