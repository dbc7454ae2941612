import re
import sys
import tomllib
from pathlib import Path

import pytest
import typer
from typer.testing import CliRunner

from orchestrator.cli import app
from orchestrator.cli.common import EXTRAS, SessionProgress
from orchestrator.cli.session_cmd import FaultHints, print_status
from processing.offline import STAGES, MdfStage
from rig.errors import KinematicsError

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


@pytest.mark.slow  # waits out the client's retries
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


def test_sim_render_without_the_simulator_names_the_extra(tmp_path, monkeypatch):
    for name in [m for m in sys.modules if m == "sim" or m.startswith("sim.")]:
        monkeypatch.delitem(sys.modules, name)  # so the simulator is imported afresh
    monkeypatch.setitem(sys.modules, "trimesh", None)
    args = ["sim", "render", "examples/scenes/bumps.toml", "--out", str(tmp_path)]
    result = runner.invoke(app, args)
    assert result.exit_code == 1, result.output
    assert "btfrig[sim]" in result.output


# -- one error path: exit 2 for invalid input, 1 for a failure, one message, no traceback --


def _fails_cleanly(result, code: int, *needles: str) -> None:
    assert result.exit_code == code, result.output
    assert "Traceback" not in result.output, result.output
    assert result.output.count("error:") == 1, result.output
    for needle in needles:
        assert needle in result.output, (needle, result.output)


def _nested(depth: int) -> str:
    return f'[sample]\nname = "x"\n[output]\narchive = {"[" * depth}{"]" * depth}\n'


@pytest.mark.parametrize(
    ("content", "needle"),
    [
        (b"\xff\xfe[sample]\n", "not UTF-8"),
        (_nested(3000).encode(), "nests arrays or inline tables too deeply"),
        (_nested(300).encode(), "output.archive: Input should be a valid string"),
    ],
)
def test_plan_that_cannot_be_read_is_named(tmp_path, content, needle):
    plan = tmp_path / "p.toml"
    plan.write_bytes(content)
    result = runner.invoke(app, ["plan", str(plan)])
    _fails_cleanly(result, 2, str(plan), needle)
    assert len(result.output) < 1000  # a huge input is shown shortened


def test_plan_that_is_a_folder_is_named(tmp_path):
    _fails_cleanly(runner.invoke(app, ["plan", str(tmp_path)]), 2, str(tmp_path), "is a folder")


def test_binary_rig_config_and_scene_are_named(tmp_path):
    binary = tmp_path / "b.toml"
    binary.write_bytes(b"\x00\x9f\x92\x96 binary")
    result = runner.invoke(app, ["plan", str(EXAMPLES / "demo.toml"), "-c", str(binary)])
    _fails_cleanly(result, 2, f"rig config {binary}", "not UTF-8")
    result = runner.invoke(app, ["sim", "render", str(binary), "--out", str(tmp_path / "o")])
    _fails_cleanly(result, 2, f"scene {binary}", "not UTF-8")


@pytest.mark.parametrize(
    ("args", "needles"),
    [
        (["--on-fault", "explode"], ["--on-fault explode", "'pause' or 'fail'"]),
        (["--port", "70000"], ["--port 70000", "65532"]),
    ],
)
def test_daemon_options_are_checked(args, needles):
    _fails_cleanly(runner.invoke(app, ["daemon", *args]), 2, *needles)


def test_daemon_certificates_must_exist(tmp_path):
    # a path longer than a terminal line: the message must keep it whole at any width
    key = tmp_path / ("certificates-" * 8) / "none.key"
    result = runner.invoke(app, ["daemon", "--curve-secret-key", str(key)])
    assert result.exit_code == 2
    assert f"'{key}' does not exist" in result.output, result.output


def test_brackets_in_a_message_are_shown(tmp_path):
    plan = tmp_path / "p.toml"
    plan.write_text('[sample]\nname = "x"\n[captures]\n')
    result = runner.invoke(app, ["plan", str(plan)])
    _fails_cleanly(result, 2, "add [captures.btf], .ps, .mdf or .fixed")
    result = runner.invoke(app, ["process", str(tmp_path / "a.zarr"), "--stages", "foo"])
    _fails_cleanly(result, 2, "unknown stage(s) ['foo']; valid are ['btf', 'mdf', 'pbr', 'ps']")


def test_debug_shows_the_traceback(tmp_path):
    _fails_cleanly(runner.invoke(app, ["plan", str(tmp_path)]), 2)
    result = runner.invoke(app, ["--debug", "plan", str(tmp_path)])
    assert result.exit_code == 2
    assert "Traceback" in result.output and "is a folder" in result.output


def test_an_unexpected_error_is_one_message(monkeypatch):
    def broken(path):
        raise ZeroDivisionError("division by zero")

    monkeypatch.setattr("orchestrator.cli.plan_cmd.load_plan", broken)
    result = runner.invoke(app, ["plan", str(EXAMPLES / "demo.toml")])
    _fails_cleanly(result, 1, "unexpected ZeroDivisionError: division by zero", "rig --debug")


def test_process_without_dask_names_the_extra(monkeypatch, tmp_path):
    monkeypatch.setitem(sys.modules, "distributed", None)  # as if not installed
    result = runner.invoke(app, ["process", str(tmp_path / "a.zarr")])
    _fails_cleanly(result, 1, "'distributed' is not installed", "pip install 'btfrig[dask]'")


def test_every_extra_named_for_a_missing_package_exists():
    extras = tomllib.loads(Path("pyproject.toml").read_text())["project"]["optional-dependencies"]
    assert set(EXTRAS.values()) <= set(extras)
    for module, extra in EXTRAS.items():
        if module not in ("OpenGL", "distributed"):  # installed as PyOpenGL, dask[distributed]
            assert any(req.lower().startswith(module.lower()) for req in extras[extra]), module


def test_run_refuses_an_archive_under_a_file(tmp_path):
    (tmp_path / "afile").write_text("")
    target = tmp_path / "afile" / "x.zarr"
    args = ["run", str(EXAMPLES / "demo.toml"), "--sim", "examples/scenes/bumps.toml"]
    result = runner.invoke(app, [*args, "--archive", str(target)])
    _fails_cleanly(result, 2, f"--archive {target}", f"{tmp_path / 'afile'} is a file")
    result = runner.invoke(app, [*args, "--archive", str(tmp_path / "afile")])
    _fails_cleanly(result, 2, "exists", "rig resume")


def test_replay_refuses_an_output_under_a_file(tmp_path):
    (tmp_path / "afile").write_text("")
    target = tmp_path / "afile" / "r.zarr"
    result = runner.invoke(app, ["replay", "any.zarr", "--out", str(target)])
    _fails_cleanly(result, 2, f"--out {target}", f"{tmp_path / 'afile'} is a file")


def test_a_damaged_archive_is_named(tmp_path):
    damaged = tmp_path / "d.zarr"
    damaged.mkdir()
    (damaged / "zarr.json").write_text("not json")
    for args in (["process", str(damaged)], ["replay", str(damaged), "--max"]):
        _fails_cleanly(runner.invoke(app, args), 1, f"{damaged}/zarr.json")


def test_a_second_daemon_on_a_taken_port_says_so():
    from orchestrator.local import daemon_thread
    from orchestrator.wire.endpoints import DaemonSettings
    from rig.config import default_rig_config

    with daemon_thread(default_rig_config(), settings=DaemonSettings(port=0)) as first:
        port = int(first.control.rsplit(":", 1)[1])
        result = runner.invoke(app, ["daemon", "--port", str(port)])
    _fails_cleanly(result, 1, f"ports {port}–{port + 3}", "Address already in use", "--port")


# -- a saturated session: nothing registers, so btf has nothing to compress --

SATURATED_PLAN = """
[sample]
name = "saturated"
[captures.btf]
views = [[0, 0]]
lights = {theta_deg = 45, count = 3}
[captures.mdf]
views = [[0, 0]]
laser_locations = [[45, 0]]
scan_step_deg = 4.0
"""


def _record(tmp: Path, radiometry: dict) -> Path:
    """A finished session of the bumps scene, with ``radiometry`` replaced."""
    from orchestrator.local import run_local
    from rig.clock import VirtualClock
    from sim.rig import SimulatedRig
    from sim.scene import scene_from_dict

    scene = tomllib.loads(Path("examples/scenes/bumps.toml").read_text())
    scene["render"]["scale"] = 0.2
    scene["effects"] = ["laser", "saturation"]
    scene["radiometry"] = radiometry
    (tmp / "plan.toml").write_text(SATURATED_PLAN)
    clock = VirtualClock()
    with SimulatedRig(scene_from_dict(scene), clock=clock) as sim:
        final = run_local(tmp / "plan.toml", sim.rig_config(), archive=tmp / "s.zarr", clock=clock)
    assert final["state"] == "done", final
    return tmp / "s.zarr"


@pytest.fixture(scope="module")
def saturated(tmp_path_factory):
    """A session of a scene so bright that every frame clips."""
    return _record(tmp_path_factory.mktemp("saturated"), {"full_scale_exposure": 1e-6})


@pytest.fixture(scope="module")
def black(tmp_path_factory):
    """A session of lamps so weak that every frame is black."""
    return _record(tmp_path_factory.mktemp("black"), {"intensity_w_sr": 1e-9})


@pytest.mark.parametrize("session", ["saturated", "black"])
def test_a_stage_that_can_use_nothing_is_skipped_and_the_others_run(request, session, tmp_path):
    from rig.archive import Archive

    archive = request.getfixturevalue(session)
    previews = tmp_path / "previews"
    args = ["process", str(archive), "--stages", "btf,mdf", "--size", "16"]
    result = runner.invoke(app, [*args, "--previews", str(previews)])
    _fails_cleanly(result, 1, "1 of 2 stage(s) skipped: btf")
    assert "btf: skipped — no view slot could be registered" in result.output
    assert "3 frame(s) flagged: TOO_FEW_MARKERS ×3" in result.output
    assert "mdf: 1 item(s) → material/mdf" in result.output
    with Archive.open(archive, mode="r") as recorded:
        assert "mdf" in recorded.material and "btf" not in recorded.material
    assert [p.name for p in previews.iterdir()] == ["cam0_tt000.0_mdf.png"]


def test_a_stage_the_session_did_not_capture_is_skipped_with_the_reason(saturated, tmp_path):
    args = ["process", str(saturated), "--size", "16", "--previews", str(tmp_path)]
    result = runner.invoke(app, [*args, "--stages", "ps,mdf"])
    assert result.exit_code == 0, result.output
    said = " ".join(result.output.split())  # whatever the terminal's width
    assert "ps: skipped — the archive has no ps captures: its plan captures btf, mdf" in said
    assert "mdf: 1 item(s) → material/mdf" in said
    # nothing at all to do is still a request the archive cannot serve
    result = runner.invoke(app, [*args, "--stages", "ps"])
    _fails_cleanly(result, 2, "nothing to process")


class PlacelessMdf(MdfStage):
    """An mdf stage whose items fail as a kinematics error (module level: Dask pickles it)."""

    def compute(self, archive_path, item):
        raise KinematicsError("the lab's kinematics cannot place this step")


def test_a_stage_that_fails_is_one_message_without_dasks_traceback(saturated, monkeypatch, caplog):
    monkeypatch.setitem(STAGES, "mdf", PlacelessMdf)
    result = runner.invoke(app, ["process", str(saturated), "--stages", "mdf", "--size", "16"])
    _fails_cleanly(result, 2, "the lab's kinematics cannot place this step")
    # Dask's worker logs the task's traceback (to stderr, under the command's one message)
    assert not [r for r in caplog.records if "Compute Failed" in r.getMessage()], caplog.text


@pytest.mark.parametrize(
    ("args", "code", "needle"),
    [
        (["--previews", "/proc/x"], 2, "--previews /proc/x: cannot create the folder"),
        (["--scheduler", "garbage"], 2, "scheduler 'garbage' is not a Dask scheduler address"),
    ],
)
def test_process_options_are_checked(saturated, args, code, needle):
    result = runner.invoke(app, ["process", str(saturated), "--stages", "mdf", *args])
    _fails_cleanly(result, code, needle)


def test_resume_of_a_finished_session_is_refused(saturated):
    # refused before any daemon is asked: none listens on port 1
    result = runner.invoke(app, ["resume", str(saturated), "--connect", "tcp://127.0.0.1:1"])
    _fails_cleanly(result, 1, str(saturated), "finished", "nothing to resume")


def test_sim_serve_rejects_an_unknown_rig_kind():
    result = runner.invoke(app, ["sim", "examples/scenes/bumps.toml", "--config-kind", "tripod"])
    assert result.exit_code == 2
    assert "tripod" in result.output and "'virtex'" in result.output


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--mounts", "45,x"], "--mounts '45,x': expected numbers separated by commas"),
        (["--mounts", "45,20,10"], r"laser: mount_theta_deg \[45.0, 20.0, 10.0\]: .*1 or 2 mounts"),
        (["--mounts", "45,95"], r"laser.mount_theta_deg.1: Input should be less than or equal"),
        (["--view", "30"], "--view '30': expected 2 numbers"),
    ],
)
def test_sim_coverage_rejects_bad_input(args, message):
    result = runner.invoke(app, ["sim", "coverage", "examples/scenes/default.toml", *args])
    assert result.exit_code == 2
    assert re.search(message, " ".join(result.output.split()))


def test_sim_coverage_prints_the_table_and_the_chosen_locations():
    args = ["sim", "coverage", "examples/scenes/default.toml", "--size", "24", "--even", "1,4"]
    result = runner.invoke(app, [*args, "--mounts", "45", "--mounts", "45,20", "--start", "4"])
    assert result.exit_code == 0, result.output
    rows = [line.split("|")[1:-1] for line in result.output.splitlines() if line.startswith("| 4")]
    assert [(r[0].strip(), r[2].strip()) for r in rows] == [
        ("45", "1 even at 45°"), ("45", "4 even at 45°"),
        ("45, 20", "greedy to 99%"), ("45, 20", "4 even + greedy"),
    ]  # fmt: skip
    assert float(rows[1][3]) < 0.95 <= 0.99 <= float(rows[3][3])
    assert "laser_locations = [[45, 0], [45, 90], [45, 180], [45, 270], [20," in result.output


def _command_paths(command, path=()):
    """Every command of the `rig` tree, as the words that reach it."""
    yield path
    for name, sub in getattr(command, "commands", {}).items():
        yield from _command_paths(sub, (*path, name))


@pytest.mark.parametrize("path", list(_command_paths(typer.main.get_command(app))), ids=" ".join)
def test_help_reads_whole_at_80_columns(path):
    result = runner.invoke(app, [*path, "--help"], env={"COLUMNS": "80"})
    assert result.exit_code == 0, result.output
    assert max(len(line) for line in result.output.splitlines()) <= 80, result.output
    lines = result.output.splitlines()
    assert not [line for line in lines if line.rstrip(" │").endswith("…")]  # nothing cut short
    assert "<bool>" not in result.output  # a flag takes no value
    assert "%%" not in result.output
    assert "---" not in result.output  # no internal parameter shown as an option


def test_light_syntax_is_whole_in_view_help():
    result = runner.invoke(app, ["view", "--help"], env={"COLUMNS": "80"})
    assert "dir:THETA,PHI[:INTENSITY[:R,G,B]]" in result.output
    assert "point:X,Y,Z[:IRRADIANCE[:R,G,B]]" in result.output


@pytest.mark.parametrize("request_name", ["pause", "abort", "shutdown"])
def test_steering_commands_have_no_hidden_request_option(request_name):
    result = runner.invoke(
        app, [request_name, "---name", "shutdown", "--connect", "tcp://127.0.0.1:1"]
    )
    assert result.exit_code == 2 and "No such option: ---name" in result.output, result.output


def test_session_events_and_status_are_printed_as_words(capsys):
    fault = {"device": "light arc", "operation": "move", "detail": "stalled", "step": 4}
    with SessionProgress() as view:
        view({"topic": "log", "seq": 3, "time": 1.0, "kind": "session", "action": "start",
              "session": "abc", "committed": 0})  # fmt: skip
        view({"topic": "log", "seq": 4, "time": 2.0, "kind": "fault", **fault})
    print_status({"state": "paused", "session": {"session": "abc", "fault": fault}})
    out = capsys.readouterr().out
    assert "session start: session abc, committed 0" in out, out
    assert "fault: device light arc, operation move, detail stalled, step 4" in out, out
    assert "{" not in out and "'" not in out, out


def test_a_follower_that_joined_after_the_fault_is_told_what_to_do_once(capsys):
    # A fault at the first step can come before `rig run`'s client subscribed: it sees
    # no fault event, only statuses of the paused session (one a second).
    fault = {"device": "lamp bank", "operation": "switch", "detail": "stays dark", "step": 0}
    seen = []
    hints = FaultHints(seen.append)
    hints({"topic": "daemon", "control": "tcp://127.0.0.1:5999"})
    for seq in (None, 7, 8):
        hints({"topic": "status", "seq": seq, "state": "paused", "session": {"fault": fault}})
    said = " ".join(capsys.readouterr().out.split())
    assert len(seen) == 4
    assert said.count("paused: lamp bank failed at step 0 (switch: stays dark)") == 1, said
    assert "`rig resume --connect tcp://127.0.0.1:5999` to retry that step" in said
    hints({"topic": "state", "event": "resume", "from": "paused", "to": "running"})
    hints({"topic": "state", "event": "fault", "from": "running", "to": "paused", **fault})
    hints({"topic": "status", "seq": 9, "state": "paused", "session": {"fault": fault}})
    assert capsys.readouterr().out.count("paused: lamp bank failed") == 1


def test_a_long_compile_says_what_it_is_doing():
    result = runner.invoke(app, ["plan", str(EXAMPLES / "demo.toml"), "--estimate"])
    assert result.exit_code == 0, result.output
    assert "compiling the plan for the wang rig default" in result.stderr
