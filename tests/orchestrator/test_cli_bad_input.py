"""Bad input and failures reach the user as one message naming what, with exit 2 for
invalid input and 1 for a failure: live stages, fault tables, output paths, a plan the
rig cannot do, damaged chunks and worker errors under Dask, a full disk."""

import logging
import re
import shutil
import tomllib
from pathlib import Path

import pytest
from typer.testing import CliRunner

from orchestrator.cli import app
from rig.archive import Archive
from tests.rig.archive import test_disk_full
from tests.rig.interchange.conftest import SIZE, write_ubo_folder
from tests.rig.material.conftest import make_archive, ps_view

EXAMPLES = Path(__file__).parents[2] / "examples"
runner = CliRunner()
#: a 1 MiB tmpfs (skipped where none can be mounted)
small_disk = test_disk_full.small_disk


def _run(*args):
    result = runner.invoke(app, [str(a) for a in args])
    assert "Traceback" not in result.output, result.output
    return result


def _said(result) -> str:
    return " ".join(result.output.split())


def _imported(tmp_path, where=None) -> Path:
    """An imported UBO2003 set (3 views × 5 lights, 32²): a btf archive in seconds."""
    archive = (where or tmp_path) / "a.zarr"
    result = _run("import", write_ubo_folder(tmp_path / "ubo"), "--out", archive)
    assert result.exit_code == 0, result.output
    return archive


def _fill(disk: Path) -> None:
    """Leave no free byte on the filesystem of ``disk``."""
    with open(disk / "filler", "ab") as filler:
        filler.write(bytes(shutil.disk_usage(disk).free))


def _corrupt_chunk(archive: Path, step: int) -> Path:
    """Overwrite bytes inside a frame chunk, keeping its size (a bit rot the size check
    cannot see)."""
    chunk = next((archive / "frames").glob(f"*/c.{step}.0.0.0"))
    data = bytearray(chunk.read_bytes())
    data[40:60] = bytes(20)
    chunk.write_bytes(bytes(data))
    return chunk


@pytest.fixture
def dask_reports():
    """The records Dask's worker logger lets through while a test runs."""
    records: list[logging.LogRecord] = []
    handler = logging.Handler()
    handler.emit = records.append
    worker_log = logging.getLogger("distributed.worker")
    worker_log.addHandler(handler)
    yield records
    worker_log.removeHandler(handler)


# -- rig run, rig sim, rig submit ---------------------------------------------------------


def test_run_with_an_unknown_live_stage_exits_2_before_anything_runs(tmp_path):
    archive = tmp_path / "s.zarr"
    result = _run("run", EXAMPLES / "plans" / "demo.toml", "--sim", EXAMPLES / "scenes" /
                  "bumps.toml", "--archive", archive, "--stages", "stats,nonsense")  # fmt: skip
    assert result.exit_code == 2, result.output
    assert "--stages: live stage(s) 'stats,nonsense': unknown ['nonsense']" in _said(result)
    assert not archive.exists()


@pytest.mark.parametrize(
    ("fault", "says"),
    [
        ("cameras.nonsense=3", "cameras: unknown fault(s) ['nonsense']; valid are"),
        ("cameras.dropped_frames=-1", "cameras: fault dropped_frames = -1; expected a whole"),
        ("cameras.camera_id=3", "cameras: fault camera_id = 3; expected a camera id"),
    ],
)
def test_sim_with_a_bad_camera_fault_exits_2_naming_it(tmp_path, fault, says):
    config = tmp_path / "c.toml"
    result = _run("sim", EXAMPLES / "scenes" / "bumps.toml", "--config-out", config,
                  "--fault", fault)  # fmt: skip
    assert result.exit_code == 2, result.output
    assert says in _said(result) and not config.exists()


def test_sim_config_out_under_a_file_exits_2_before_the_peers_start(tmp_path):
    (tmp_path / "afile").write_text("")
    result = _run("sim", EXAMPLES / "scenes" / "bumps.toml", "--config-out",
                  tmp_path / "afile" / "x.toml")  # fmt: skip
    assert result.exit_code == 2, result.output
    assert f"--config-out {tmp_path / 'afile' / 'x.toml'}: {tmp_path / 'afile'} is a file" in (
        _said(result)
    )


def test_view_of_no_material_exits_2_naming_the_path_whole(tmp_path):
    missing = tmp_path / "take[one]" / "m.zarr"  # brackets: rich markup must not eat them
    result = _run("view", missing, "--out", tmp_path / "v.png")
    assert result.exit_code == 2, result.output
    assert f"{missing}: no zarr.json here" in _said(result)


def test_a_plan_the_rig_cannot_do_exits_2_from_run_and_submit(tmp_path):
    from orchestrator.local import daemon_thread
    from orchestrator.wire.endpoints import DaemonSettings
    from rig.config import load_rig_config

    plan = EXAMPLES / "plans" / "demo.toml"
    result = _run("run", plan, "--sim", EXAMPLES / "scenes" / "virtex.toml",
                  "--archive", tmp_path / "r.zarr")  # fmt: skip
    assert result.exit_code == 2, result.output
    assert "plan vs rig config" in _said(result) and "a VirTex stage" in _said(result)
    virtex = load_rig_config(EXAMPLES / "rigs" / "virtex.toml")
    with daemon_thread(virtex, settings=DaemonSettings(port=0)) as endpoints:
        result = _run("submit", plan, "--archive", tmp_path / "s.zarr",
                      "--connect", endpoints.control)  # fmt: skip
    assert result.exit_code == 2, result.output
    assert "plan_invalid" in _said(result) and "a VirTex stage" in _said(result)


# -- rig process and rig replay: what the workers raise ----------------------------------


def test_a_corrupt_chunk_under_process_is_one_line_naming_it(tmp_path, dask_reports):
    archive = _imported(tmp_path)
    chunk = _corrupt_chunk(archive, 4)
    result = _run("process", archive, "--stages", "btf", "--size", SIZE, "--components", 4)
    assert result.exit_code == 1, result.output
    assert f"chunk file {chunk} is corrupt" in _said(result)
    assert "Compute Failed" not in result.output
    assert not [r for r in dask_reports if "Compute Failed" in str(r.msg)]


def test_an_unforeseen_worker_error_names_the_stage_and_the_item(
    tmp_path, monkeypatch, dask_reports
):
    def broken(*args, **kwargs):
        raise ValueError("operands could not be broadcast together")

    # what the stage calls on the worker (the stage itself travels to Dask by reference)
    monkeypatch.setattr("processing.offline.btf.slot_normtextures", broken)
    archive = _imported(tmp_path)
    result = _run("process", archive, "--stages", "btf", "--size", SIZE)
    assert result.exit_code == 1, result.output
    said = _said(result)
    stage_and_item = r"error: stage btf, view slot \d \(\d+°, \d+°\): ValueError: operands"
    assert re.search(stage_and_item, said), said
    assert "unexpected" not in said and "Compute Failed" not in result.output
    assert not [r for r in dask_reports if "Compute Failed" in str(r.msg)]


def test_a_corrupt_chunk_under_replay_fails_the_session_without_a_traceback(tmp_path, caplog):
    from orchestrator.local import run_local
    from rig.clock import VirtualClock
    from sim.rig import SimulatedRig
    from sim.scene import scene_from_dict

    scene = tomllib.loads((EXAMPLES / "scenes" / "bumps.toml").read_text())
    scene["render"]["scale"] = 0.2
    scene["effects"] = []
    plan = tmp_path / "plan.toml"
    plan.write_text('[sample]\nname = "s"\n[captures.btf]\nviews = [[0, 0]]\n'
                    "lights = {theta_deg = 45, count = 3}\n")  # fmt: skip
    clock = VirtualClock()
    with SimulatedRig(scene_from_dict(scene), clock=clock) as sim:
        final = run_local(plan, sim.rig_config(), archive=tmp_path / "s.zarr", clock=clock)
    assert final["state"] == "done", final
    chunk = _corrupt_chunk(tmp_path / "s.zarr", 1)
    caplog.clear()
    result = _run("replay", tmp_path / "s.zarr", "--max")
    assert result.exit_code == 1, result.output
    assert f"chunk file {chunk} is corrupt" in _said(result)
    failed = [r for r in caplog.records if "failed" in r.getMessage()]
    assert failed and not [r for r in caplog.records if r.exc_info], caplog.text


# -- a full disk: a failure (exit 1) naming what could not be written ----------------------


def test_process_on_a_full_disk_names_the_result_and_keeps_the_old_one(tmp_path, small_disk):
    archive = _imported(tmp_path, small_disk)
    _fill(small_disk)
    result = _run("process", archive, "--stages", "btf", "--size", SIZE, "--components", 4)
    assert result.exit_code == 1, result.output
    said = _said(result)
    assert f"{archive}/material/btf: writing the btf result failed: No space left" in said
    assert not (archive / "material" / "btf").exists()


def test_gltf_on_a_full_disk_names_out_and_leaves_nothing(tmp_path, small_disk):
    archive = make_archive(tmp_path / "s.zarr", ps=[ps_view("cam0_tt000.0")])
    _fill(small_disk)
    out = small_disk / "out.glb"
    result = _run("export", "gltf", archive, "--out", out)
    assert result.exit_code == 1, result.output
    assert f"--out {out}: writing failed: No space left on device" in _said(result)
    assert sorted(p.name for p in small_disk.iterdir()) == ["filler"]


@pytest.mark.parametrize("fmt", ["png16", "tiff", "exr"])
def test_frames_on_a_full_disk_exit_1_naming_out(tmp_path, small_disk, fmt):
    archive = _imported(tmp_path)
    _fill(small_disk)
    out = small_disk / "frames"
    result = _run("export", fmt, archive, "--out", out)
    assert result.exit_code == 1, result.output
    said = _said(result)
    assert f"--out {out}: " in said and "could not be written" in said
    assert sorted(p.name for p in small_disk.iterdir()) == ["filler"]


def test_process_views_names_the_valid_ones_and_the_material_records_the_choice(tmp_path):
    archive = _imported(tmp_path)
    result = _run("process", archive, "--stages", "btf", "--size", SIZE, "--views", "texel")
    assert result.exit_code == 2, result.output
    assert "--views 'texel': valid are nominal, per-texel" in _said(result)
    views = {}
    for choice in ("nominal", "per-texel"):
        result = _run("process", archive, "--stages", "btf", "--size", SIZE, "--views", choice)
        assert result.exit_code == 0, result.output
        with Archive.open(archive, mode="r") as recorded:
            views[choice] = recorded.material["btf"].attrs["radiometry"]["skipped"].get("view")
    assert "views 'nominal'" in views["nominal"]
    # an imported set has normtextures and no camera: the stage tried, and says why not
    assert views["per-texel"].startswith("imported normtextures: no camera to place")


def test_process_lights_names_the_valid_ones_and_the_material_says_why_not(tmp_path):
    archive = _imported(tmp_path)
    result = _run("process", archive, "--stages", "btf", "--size", SIZE, "--lights", "own")
    assert result.exit_code == 2, result.output
    assert "--lights 'own': valid are nominal, per-texel" in _said(result)
    result = _run("process", archive, "--stages", "btf", "--size", SIZE, "--lights", "per-texel")
    assert result.exit_code == 0, result.output
    with Archive.open(archive, mode="r") as recorded:
        skipped = recorded.material["btf"].attrs["radiometry"]["skipped"]
    # an imported set has normtextures and no lamp to place: the stage tried, and says why not
    assert skipped["light"].startswith("imported normtextures: no lamp to place")
