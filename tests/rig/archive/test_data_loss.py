"""Nothing recorded is lost: crafted names, truncated journals and crash leftovers.

Each case opens a damaged or crafted archive the way ``rig process`` and
``rig resume`` do (``mode="a"``) and checks that every chunk file is still
there, byte for byte, and that the damage is named.
"""

import json
import shutil

import pytest

from rig.archive import Archive, ArchiveDamaged, ArchiveError
from tests.rig.archive.sessions import (
    CAMERAS,
    assert_frames,
    build_session,
    chunk_files,
    step_frames,
    step_record,
)

N_STEPS = 12


@pytest.fixture
def session(tmp_path):
    return build_session(tmp_path / "good.zarr", N_STEPS)


def _journal(path):
    return path / "log" / "journal.jsonl"


@pytest.mark.parametrize("mode", ["a", "r"])
def test_a_crafted_camera_name_cannot_reach_another_archive(session, mode):
    evil = session.with_name("evil.zarr")
    shutil.copytree(session, evil)
    root = json.loads((evil / "zarr.json").read_text())
    crafted = "../../good.zarr/frames/cam0"
    root["attributes"]["cameras"][crafted] = CAMERAS["cam0"].to_json()
    (evil / "zarr.json").write_text(json.dumps(root))
    before = chunk_files(session)
    with pytest.raises(
        ArchiveDamaged,
        match=r"zarr\.json: attribute cameras: camera name '\.\./\.\./good\.zarr/frames/cam0': "
        r"use 1–64 letters, digits",
    ):
        Archive.open(evil, mode=mode)
    assert chunk_files(session) == before
    assert_frames(session, range(N_STEPS))


@pytest.mark.parametrize("name", ["../x", "a/b", ".hidden", "-x", "", "x" * 65])
def test_a_camera_name_that_is_not_one_path_component_is_refused(tmp_path, name):
    with pytest.raises(ArchiveError, match="camera name"):
        Archive.create(tmp_path / "s.zarr", plan={}, rig_config={}, cameras={name: CAMERAS["cam0"]})
    assert not (tmp_path / "s.zarr").exists()


@pytest.mark.parametrize("cut", ["half", "five lines"])
@pytest.mark.parametrize("mode", ["a", "r"])
def test_a_truncated_journal_is_damage_and_no_frame_is_touched(session, cut, mode):
    journal = _journal(session)
    data = journal.read_bytes()
    if cut == "half":
        journal.write_bytes(data[: len(data) // 2])
    else:
        journal.write_bytes(b"".join(data.splitlines(keepends=True)[:-5]))
    before = chunk_files(session)
    with pytest.raises(ArchiveDamaged, match=r"steps are committed, but chunk files past") as err:
        Archive.open(session, mode=mode)
    message = str(err.value)
    assert "frames/cam0: " in message and "the journal lost records" in message
    assert f"rig repair {session}" in message
    assert chunk_files(session) == before
    assert journal.read_bytes() != data  # nothing was "recovered" into the journal either
    assert not (session / "quarantine").exists()


@pytest.mark.parametrize("mode", ["a", "r"])
def test_an_emptied_journal_is_damage(session, mode):
    _journal(session).write_bytes(b"")
    before = chunk_files(session)
    with pytest.raises(ArchiveDamaged, match=r"the journal is empty, but chunk files are present"):
        Archive.open(session, mode=mode)
    assert chunk_files(session) == before
    assert _journal(session).read_bytes() == b""


def test_a_lost_calibration_record_is_damage(tmp_path):
    path = build_session(tmp_path / "s.zarr", 2, calibration={"gain": 2.0})
    lines = _journal(path).read_bytes().splitlines(keepends=True)
    assert [json.loads(line)["kind"] for line in lines[-2:]] == ["calibration", "closed"]
    _journal(path).write_bytes(b"".join(lines[:-2]))
    with pytest.raises(
        ArchiveDamaged,
        match=r"calibration version 0 in the journal, but calibration/zarr\.json mirrors version 1",
    ):
        Archive.open(path, mode="a")


def test_crash_leftovers_are_moved_to_the_quarantine_not_deleted(session):
    # What a crash during step 12 leaves: its chunk files, half a commit line.
    with Archive.open(session, mode="a", fsync=False) as archive:
        archive.append_step(step_record(N_STEPS), step_frames(N_STEPS))
    journal = _journal(session)
    lines = journal.read_bytes().splitlines(keepends=True)
    step_line = lines[-2]  # the step record, then "closed"
    torn = step_line[: len(step_line) // 3]
    journal.write_bytes(b"".join(lines[:-2]) + torn)
    leftovers = {
        name: data
        for name, data in chunk_files(session).items()
        if int(name.split("/")[-1].split(".")[1]) >= N_STEPS * 2
    }
    assert len(leftovers) == len(CAMERAS) * 2
    with Archive.open(session, mode="a") as archive:
        recovered = archive.recovered
        assert archive.events("opened")[-1].payload["recovered"] == recovered
    assert recovered["uncommitted_chunks/cam0"] == 2
    assert recovered["torn_journal_bytes"] == len(torn)
    folder = session / recovered["quarantine"]
    assert folder.parent == session / "quarantine"
    for name, data in leftovers.items():
        assert not (session / name).exists()
        assert (folder / name).read_bytes() == data
    assert (folder / "log" / "journal.jsonl.torn").read_bytes() == torn
    assert_frames(session, range(N_STEPS))
    # zarr readers do not see the quarantine (an array node they do not list into).
    import zarr

    group = zarr.open_group(session, mode="r")
    assert sorted(name for name, _ in group.members()) == sorted(
        ["frames", "calibration", "material", "log", "quarantine"]
    )


def test_an_interrupted_material_replacement_is_set_aside(session):
    material = session / "material"
    with Archive.open(session, mode="a") as archive, archive.replace_material("normals") as group:
        group.attrs["version"] = 1
    # A crash between the two renames of a second replacement, and one before them.
    shutil.copytree(material / "normals", material / (".old-normals-" + "a" * 32))
    shutil.copytree(material / "normals", material / (".tmp-normals-" + "b" * 32))
    with Archive.open(session, mode="a") as archive:
        recovered = archive.recovered
        assert archive.material["normals"].attrs["version"] == 1
    folder = session / recovered["quarantine"]
    assert sorted(p.name for p in (folder / "material").iterdir()) == [
        ".old-normals-" + "a" * 32,
        ".tmp-normals-" + "b" * 32,
    ]
    assert sorted(p.name for p in material.iterdir()) == ["normals", "zarr.json"]
