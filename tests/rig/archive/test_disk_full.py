"""A full disk: the write is rolled back, ArchiveFull names the path, nothing committed is lost.

One test injects ENOSPC into the journal's ``write``; the others run on a
real 1 MiB tmpfs (mounting one needs root; they are skipped without it).
"""

import errno
import os
import subprocess

import numpy as np
import pytest

from rig.archive import Archive, ArchiveFull, FrameFormat, StepRecord
from rig.archive import _journal as journal_module
from tests.rig.archive.sessions import assert_frames, build_session, step_frames, step_record


def test_a_failed_journal_write_is_cut_back_to_the_last_whole_line(tmp_path, monkeypatch):
    path = build_session(tmp_path / "s.zarr", 3)
    real_write = os.write
    with Archive.open(path, mode="a", fsync=False) as archive:
        journal_fd = archive._journal._fd

        def half_then_enospc(fd, data):
            if fd != journal_fd:
                return real_write(fd, data)
            real_write(fd, bytes(data[: len(data) // 2]))
            raise OSError(errno.ENOSPC, "No space left on device")

        monkeypatch.setattr(journal_module.os, "write", half_then_enospc)
        full = r"journal\.jsonl: disk full while writing a 'step'"
        with pytest.raises(ArchiveFull, match=full) as err:
            archive.append_step(step_record(3), step_frames(3))
        assert err.value.path == path / "log" / "journal.jsonl"
        assert err.value.needed_bytes > 100
        assert (path / "log" / "journal.jsonl").read_bytes().endswith(b"\n")
        monkeypatch.setattr(journal_module.os, "write", real_write)  # space is back
        archive.append_step(step_record(3), step_frames(3))
    assert_frames(path, range(4))


@pytest.fixture
def small_disk(tmp_path):
    """A 1 MiB tmpfs at ``tmp_path / "disk"``, unmounted afterwards."""
    mount_point = tmp_path / "disk"
    mount_point.mkdir()
    done = subprocess.run(
        ["mount", "-t", "tmpfs", "-o", "size=1m", "tmpfs", str(mount_point)],
        capture_output=True,
        check=False,
    )
    if done.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs (needs root): {done.stderr.decode().strip()}")
    try:
        yield mount_point
    finally:
        # Lazy: a failed test may still hold a file open in it.
        subprocess.run(["umount", "--lazy", str(mount_point)], check=True)


_NOISE = FrameFormat(96, 128, 3, "uint8")  # 36 KiB a frame, incompressible


def _noise_step(index: int) -> tuple[StepRecord, dict[str, list[np.ndarray]]]:
    rng = np.random.default_rng(index)
    frames = [rng.integers(0, 256, _NOISE.shape, dtype=np.uint8) for _ in range(2)]
    return StepRecord(index=index, kind="btf", cameras=("cam0",), exposures_s=(0.01,)), {
        "cam0": frames
    }


def _fill(path) -> None:
    """Write to ``path`` (made while there was space) until the filesystem is full."""
    with open(path, "ab", buffering=0) as f, pytest.raises(OSError, match="No space left"):
        _write_forever(f)


def _write_forever(f) -> None:
    while True:
        f.write(b"\0" * 4096)


def _append_until_it_fails(archive, committed: dict) -> None:
    for index in range(100):
        step, frames = _noise_step(index)
        archive.append_step(step, frames)
        committed[index] = frames["cam0"]


def test_disk_full_during_a_session_then_resume(small_disk):
    path = small_disk / "s.zarr"
    filler = small_disk / "filler"
    filler.touch()
    committed = {}
    archive = Archive.create(path, plan={}, rig_config={}, cameras={"cam0": _NOISE})
    with pytest.raises(ArchiveFull) as err:
        _append_until_it_fails(archive, committed)
    assert 5 < len(committed) < 30
    assert err.value.path.parent in (path / "frames" / "cam0", path / "log")
    assert f"{err.value.path}: disk full while writing" in str(err.value)
    assert "MB free" in str(err.value)
    assert err.value.needed_bytes >= 2 * _NOISE.nbytes
    # The failed step's chunk files are gone again: only committed frames use the space.
    chunks = sorted((path / "frames" / "cam0").glob("c.*"))
    assert len(chunks) == 2 * len(committed)
    _fill(filler)
    with pytest.raises(ArchiveFull, match=r"journal\.jsonl: disk full while writing a 'note'"):
        archive.log_event("note", text="x" * 20_000)
    archive._release()  # the process dies here; the lock goes with it
    filler.unlink()  # space returns
    resumed = Archive.open(path, mode="a")
    assert "torn_journal_bytes" not in resumed.recovered
    assert resumed.committed_steps() == tuple(committed)
    for index, frames in committed.items():
        for sub, image in enumerate(frames):
            np.testing.assert_array_equal(resumed.read_frame(index, "cam0", sub), image)
    resumed.log_event("note", text="space is back")
    resumed.close()
    with Archive.open(path) as reopened:
        assert reopened.committed_steps() == tuple(committed)
        assert reopened.events("note")[-1].payload == {"text": "space is back"}


def test_a_torn_line_from_a_full_disk_is_not_followed_by_the_next_record(small_disk):
    # The case that made archives unreadable: a partial record, then space
    # returns and the next record lands after it.
    path = build_session(small_disk / "s.zarr", 3)
    archive = Archive.open(path, mode="a", fsync=False)
    filler = small_disk / "filler"
    filler.touch()
    _fill(filler)
    with pytest.raises(ArchiveFull):
        archive.log_event("note", text="y" * 50_000)
    filler.unlink()
    archive.log_event("note", text="after")
    archive.close()
    assert_frames(path, range(3))
    with Archive.open(path) as reopened:
        assert [e.payload["text"] for e in reopened.events("note")] == ["after"]
