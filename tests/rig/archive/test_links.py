"""An archive's folders and files are its own: links are refused, strays set aside.

A symbolic link inside an archive could lead recovery into another archive (it
would move that archive's chunks and rewrite its metadata); a folder where a
chunk file belongs made every command fail with "Is a directory".
"""

import json
import os
import shutil

import pytest

from rig.archive import Archive, ArchiveDamaged, repair_archive
from tests.rig.archive.sessions import assert_frames, build_session

N_STEPS = 8


@pytest.fixture
def good(tmp_path):
    return build_session(tmp_path / "good.zarr", N_STEPS)


def _tree(path):
    """Every file under ``path`` (links not followed), relative path → bytes."""
    return {
        p.relative_to(path).as_posix(): p.read_bytes()
        for p in sorted(path.rglob("*"))
        if p.is_file() and not p.is_symlink()
    }


def _drop_last_step(path):
    journal = path / "log" / "journal.jsonl"
    lines = journal.read_bytes().splitlines(keepends=True)
    last = max(i for i, line in enumerate(lines) if json.loads(line)["kind"] == "step")
    journal.write_bytes(b"".join(lines[:last]))


@pytest.mark.parametrize("mode", ["a", "r"])
def test_a_camera_folder_linked_into_another_archive_is_refused(good, mode):
    evil = good.with_name("evil.zarr")
    shutil.copytree(good, evil)
    shutil.rmtree(evil / "frames" / "cam1")
    os.symlink("../../good.zarr/frames/cam1", evil / "frames" / "cam1")
    _drop_last_step(evil)
    before = _tree(good)
    with pytest.raises(ArchiveDamaged, match=r"evil\.zarr/frames/cam1: a symbolic link \(it leads"):
        Archive.open(evil, mode=mode)
    assert _tree(good) == before
    assert_frames(good, range(N_STEPS))


@pytest.mark.parametrize(
    "relative", ["frames", "material", "log", "quarantine", "log/journal.jsonl", "zarr.json"]
)
def test_any_linked_part_of_an_archive_is_refused_before_it_is_used(good, tmp_path, relative):
    elsewhere = tmp_path / "elsewhere"
    shutil.copytree(good, elsewhere)
    (elsewhere / "quarantine").mkdir()
    if (good / relative).exists():
        (good / relative).rename(tmp_path / "moved")
    os.symlink(elsewhere / relative, good / relative)
    before = _tree(elsewhere)
    with pytest.raises(ArchiveDamaged, match="a symbolic link"):
        Archive.open(good, mode="a")
    assert _tree(elsewhere) == before


def test_a_linked_writer_lock_is_refused_and_its_target_untouched(good, tmp_path):
    victim = tmp_path / "victim.txt"
    victim.write_text("keep me")
    (good / "log" / "writer.lock").unlink(missing_ok=True)
    os.symlink(victim, good / "log" / "writer.lock")
    with pytest.raises(ArchiveDamaged, match=r"writer\.lock: a symbolic link"):
        Archive.open(good, mode="a")
    assert victim.read_text() == "keep me"


@pytest.mark.parametrize("position", [N_STEPS * 2, 999])
def test_a_folder_under_a_chunk_name_is_set_aside_by_recovery(good, position):
    stray = good / "frames" / "cam0" / f"c.{position}.0.0.0"
    stray.mkdir()
    (stray / "zarr.json").write_text("{}")
    assert_frames(good, range(N_STEPS))  # a reader passes over it
    with Archive.open(good, mode="a") as archive:
        recovered = archive.recovered
    assert recovered["not_chunk_files/cam0"] == 1
    kept = good / recovered["quarantine"] / "frames" / "cam0" / stray.name
    assert (kept / "zarr.json").read_text() == "{}"
    assert not stray.exists()
    assert_frames(good, range(N_STEPS))


def test_a_linked_chunk_is_set_aside_and_its_target_untouched(good, tmp_path):
    victim = tmp_path / "victim.bin"
    victim.write_bytes(b"other data")
    os.symlink(victim, good / "frames" / "cam1" / f"c.{N_STEPS * 2}.0.0.0")
    with Archive.open(good, mode="a") as archive:
        assert archive.recovered["not_chunk_files/cam1"] == 1
    assert victim.read_bytes() == b"other data"
    assert_frames(good, range(N_STEPS))


def test_a_folder_where_a_committed_chunk_belongs_is_named(good):
    chunk = good / "frames" / "cam1" / "c.0.0.0.0"
    chunk.unlink()
    chunk.mkdir()
    with pytest.raises(ArchiveDamaged, match=r"c\.0\.0\.0\.0 is a directory, not the committed"):
        Archive.open(good)


def test_repair_sets_a_stray_folder_aside(good):
    stray = good / "frames" / "cam1" / "c.999.0.0.0"
    stray.mkdir()
    before = _tree(good / "frames")
    report = repair_archive(good)
    assert report.changed and not report.journal_rebuilt
    assert report.set_aside == ("frames/cam1/c.999.0.0.0",)
    assert (good / report.quarantine / "frames" / "cam1" / "c.999.0.0.0").is_dir()
    assert _tree(good / "frames") == before
    assert not repair_archive(good).changed


def test_a_file_where_the_quarantine_belongs_is_named(good):
    # Found by the containment property: recovery could not set anything aside.
    (good / "quarantine").write_bytes(b"planted")
    _drop_last_step(good)
    with pytest.raises(ArchiveDamaged, match=r"good\.zarr/quarantine: not a folder"):
        repair_archive(good)
    assert (good / "quarantine").read_bytes() == b"planted"
