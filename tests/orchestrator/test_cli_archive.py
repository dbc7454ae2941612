"""Damaged and crafted archives from the command line: `rig repair`, `rig process`."""

import json
import shutil

from typer.testing import CliRunner

from orchestrator.cli import app
from tests.rig.archive.sessions import CAMERAS, assert_frames, build_session, chunk_files

runner = CliRunner()


def test_repair_rebuilds_a_truncated_journal_and_says_what_it_did(tmp_path):
    path = build_session(tmp_path / "s.zarr", 6)
    journal = path / "log" / "journal.jsonl"
    lines = journal.read_bytes().splitlines(keepends=True)
    journal.write_bytes(b"".join(lines[:4]))  # created, steps 0–2
    result = runner.invoke(app, ["repair", str(path)])
    assert result.exit_code == 0, result.output
    assert "journal rebuilt: 6 committed steps, 4 records kept, 3 steps rebuilt" in result.output
    assert "(3–5)" in result.output
    assert "set aside in quarantine/" in result.output and ": 1 item(s)" in result.output
    assert_frames(path, range(6))
    again = runner.invoke(app, ["repair", str(path)])
    assert again.exit_code == 0
    assert "opens cleanly with 6 committed steps; nothing to repair" in again.output


def test_repair_of_what_is_not_an_archive_exits_1_naming_it(tmp_path):
    result = runner.invoke(app, ["repair", str(tmp_path / "nowhere.zarr")])
    assert result.exit_code == 1
    assert "nowhere.zarr: no archive here" in result.output


def test_process_of_a_crafted_archive_touches_no_other_archive(tmp_path):
    good = build_session(tmp_path / "good.zarr", 3)
    evil = tmp_path / "evil.zarr"
    shutil.copytree(good, evil)
    root = json.loads((evil / "zarr.json").read_text())
    root["attributes"]["cameras"]["../../good.zarr/frames/cam0"] = CAMERAS["cam0"].to_json()
    (evil / "zarr.json").write_text(json.dumps(root))
    before = chunk_files(good)
    result = runner.invoke(app, ["process", str(evil), "--stages", "ps"])
    assert result.exit_code == 1
    assert "camera name '../../good.zarr/frames/cam0'" in result.output
    assert chunk_files(good) == before


def test_process_of_an_archive_with_a_linked_camera_folder_exits_1_naming_it(tmp_path):
    good = build_session(tmp_path / "good.zarr", 3)
    evil = tmp_path / "evil.zarr"
    shutil.copytree(good, evil)
    shutil.rmtree(evil / "frames" / "cam0")
    (evil / "frames" / "cam0").symlink_to("../../good.zarr/frames/cam0")
    journal = evil / "log" / "journal.jsonl"
    journal.write_bytes(b"".join(journal.read_bytes().splitlines(keepends=True)[:-2]))
    before = chunk_files(good)
    result = runner.invoke(app, ["process", str(evil), "--stages", "ps"])
    assert result.exit_code == 1, result.output
    assert "evil.zarr/frames/cam0: a symbolic link" in " ".join(result.output.split())
    assert chunk_files(good) == before
    assert_frames(good, range(3))


def test_a_folder_under_a_chunk_name_is_passed_over_and_repair_sets_it_aside(tmp_path):
    path = build_session(tmp_path / "s.zarr", 3)
    (path / "frames" / "cam1" / "c.999.0.0.0").mkdir()
    out = tmp_path / "frames"
    exported = runner.invoke(app, ["export", "exr", str(path), "--out", str(out)])
    assert exported.exit_code == 0, exported.output  # it failed with "Is a directory"
    result = runner.invoke(app, ["repair", str(path)])
    assert result.exit_code == 0, result.output
    said = " ".join(result.output.split())
    assert "3 committed steps; set aside in quarantine/" in said
    assert "frames/cam1/c.999.0.0.0" in said
    assert not (path / "frames" / "cam1" / "c.999.0.0.0").exists()
