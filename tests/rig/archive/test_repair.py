"""``repair_archive`` rebuilds a lost or garbled journal from the chunks' own records."""

import json

import pytest

from rig.archive import Archive, ArchiveDamaged, StepAlreadyCommitted, repair_archive
from tests.rig.archive.sessions import (
    assert_frames,
    build_session,
    chunk_files,
    step_frames,
    step_record,
)

N_STEPS = 10


@pytest.fixture
def session(tmp_path):
    return build_session(tmp_path / "s.zarr", N_STEPS, calibration={"gain": 1.5})


def _journal(path):
    return path / "log" / "journal.jsonl"


def test_a_journal_cut_in_half_is_rebuilt_whole(session):
    journal = _journal(session)
    original = journal.read_bytes()
    journal.write_bytes(original[: len(original) // 2])
    kept = len(original[: len(original) // 2].splitlines()) - 1  # all but the torn line
    report = repair_archive(session, fsync=False)
    assert report.changed
    assert report.committed_steps == N_STEPS
    assert kept <= report.kept_records
    assert 0 < len(report.rebuilt_steps) < N_STEPS
    lost_steps = set(report.rebuilt_steps)
    assert lost_steps == set(range(min(lost_steps), N_STEPS))
    # The old journal is kept whole in the quarantine; no chunk file moved.
    folder = session / report.quarantine
    assert (folder / "log" / "journal.jsonl").read_bytes() == original[: len(original) // 2]
    assert not (folder / "frames").exists()
    assert_frames(session, range(N_STEPS))
    with Archive.open(session, mode="a") as archive:
        assert archive.calibration == {"gain": 1.5}
        assert archive.events("repaired")[-1].payload["rebuilt_steps"] == list(report.rebuilt_steps)
        rebuilt = archive.step_table()[report.rebuilt_steps[0]]
        assert rebuilt.committed_at is not None
        with pytest.raises(StepAlreadyCommitted):
            archive.append_step(step_record(3), step_frames(3))
        archive.append_step(step_record(N_STEPS), step_frames(N_STEPS))
    assert_frames(session, range(N_STEPS + 1))


def test_an_emptied_journal_is_rebuilt_with_the_mirrored_calibration(session):
    _journal(session).write_bytes(b"")
    before = chunk_files(session)
    report = repair_archive(session, fsync=False)
    assert report.rebuilt_steps == tuple(range(N_STEPS))
    assert report.kept_records == 0
    assert chunk_files(session) == before
    assert_frames(session, range(N_STEPS))
    with Archive.open(session) as archive:
        assert archive.calibration == {"gain": 1.5}
        assert archive.calibration_version == 1


def test_a_garbled_line_in_the_middle_is_set_aside_and_its_step_rebuilt(session):
    journal = _journal(session)
    lines = journal.read_bytes().splitlines(keepends=True)
    kinds = [json.loads(line)["kind"] for line in lines]
    third_step = [i for i, kind in enumerate(kinds) if kind == "step"][2]
    garbled = lines[third_step].replace(b'"kind":"step"', b'"kind":"stop"')
    journal.write_bytes(b"".join([*lines[:third_step], garbled, *lines[third_step + 1 :]]))
    with pytest.raises(ArchiveDamaged, match="the journal is damaged; `rig repair` rebuilds it"):
        Archive.open(session)
    report = repair_archive(session, fsync=False)
    assert report.rebuilt_steps == (2,)
    assert report.kept_records == len(lines) - 1
    assert any("not a whole record" in problem for problem in report.lost)
    assert_frames(session, range(N_STEPS))


def test_an_incomplete_uncommitted_step_goes_to_the_quarantine(session):
    with Archive.open(session, mode="a", fsync=False) as archive:
        archive.append_step(step_record(N_STEPS), step_frames(N_STEPS))
    # Step 10's commit line is lost with the last third of the journal, and one
    # of its chunk files never made it to disk.
    journal = _journal(session)
    data = journal.read_bytes()
    journal.write_bytes(data[: 2 * len(data) // 3])
    cut_short = session / "frames" / "cam1" / f"c.{2 * N_STEPS + 1}.0.0.0"
    cut_short.write_bytes(cut_short.read_bytes()[:10])
    report = repair_archive(session, fsync=False)
    assert report.committed_steps == N_STEPS
    assert N_STEPS not in report.rebuilt_steps
    assert any(p.startswith(f"step {N_STEPS} (from chunk records)") for p in report.lost)
    assert "frames/cam1/" + cut_short.name in report.set_aside
    assert (session / report.quarantine / "frames" / "cam1" / cut_short.name).exists()
    assert not cut_short.exists()
    assert_frames(session, range(N_STEPS))


def test_an_archive_that_opens_is_left_alone(session):
    before = _journal(session).read_bytes()
    report = repair_archive(session, fsync=False)
    assert not report.changed
    assert report.committed_steps == N_STEPS
    assert _journal(session).read_bytes() == before
    assert not (session / "quarantine").exists()


def test_missing_committed_frames_cannot_be_repaired_and_nothing_changes(session):
    journal = _journal(session)
    data = journal.read_bytes()
    journal.write_bytes(data[: len(data) // 2])
    (session / "frames" / "cam0" / "c.0.0.0.0").unlink()
    with pytest.raises(ArchiveDamaged, match=r"committed step 0, camera 'cam0', sub 0: chunk file"):
        repair_archive(session, fsync=False)
    assert journal.read_bytes() == data[: len(data) // 2]
    assert not (session / "quarantine").exists()


def test_a_missing_journal_is_rebuilt(session):
    _journal(session).unlink()
    with pytest.raises(ArchiveDamaged, match=r"missing journal journal\.jsonl; `rig repair`"):
        Archive.open(session)
    report = repair_archive(session, fsync=False)
    assert report.rebuilt_steps == tuple(range(N_STEPS))
    assert report.quarantine is None  # there was no old journal to keep
    assert_frames(session, range(N_STEPS))
