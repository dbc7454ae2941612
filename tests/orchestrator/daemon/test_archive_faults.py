"""The archive's faults through the daemon: a full disk pauses the session (naming the
path and the space needed) and resume goes on; a lost journal refuses the resume."""

import errno

import pytest

from orchestrator.client import DaemonClient, DaemonRequestError, wait_for_state
from rig.archive import Archive, ArchiveFull, _chunks
from tests.orchestrator.daemon.conftest import LAMP_PLAN, running_daemon


def test_disk_full_pauses_the_session_and_resume_retries_the_step(
    config, rig, tmp_path, monkeypatch
):
    append_step = Archive.append_step
    full_once = []

    def disk_full_at_step_2(archive, step, frames):
        if step.index == 2 and not full_once:
            full_once.append(step.index)
            raise ArchiveFull(
                archive.path / "frames" / "cam0" / "c.2.0.0.0",
                doing="step 2's 6 frames",
                needed_bytes=3_000_000,
                free_bytes=12_000,
            )
        return append_step(archive, step, frames)

    monkeypatch.setattr(Archive, "append_step", disk_full_at_step_2)
    path = tmp_path / "full.zarr"
    with (
        running_daemon(config, rig, on_fault="fail") as endpoints,
        DaemonClient(endpoints) as client,
    ):
        client.request("submit", plan_toml=LAMP_PLAN, source="test", archive=str(path))
        paused = wait_for_state(endpoints, ("paused", "failed"))
        assert paused["state"] == "paused"  # even with on_fault = "fail": space can be freed
        fault = paused["session"]["fault"]
        assert fault["device"] == "archive" and fault["step"] == 2
        assert f"{path}/frames/cam0/c.2.0.0.0: disk full" in fault["detail"]
        assert "needs about 3 MB, the filesystem has 0.012 MB free" in fault["detail"]
        assert paused["session"]["committed"] == 2
        assert rig.lamps_on == frozenset()
        client.request("resume")
        done = wait_for_state(endpoints, ("done",), settled=True)
        steps = done["session"]["steps"]
    with Archive.open(path) as archive:
        assert archive.committed_steps() == tuple(range(steps))
        assert [e.payload["device"] for e in archive.events("fault")] == ["archive"]


def test_resume_of_an_archive_whose_journal_was_emptied_is_refused(config, rig, tmp_path):
    path = tmp_path / "lost.zarr"
    with running_daemon(config, rig) as endpoints, DaemonClient(endpoints) as client:
        client.request("submit", plan_toml=LAMP_PLAN, source="test", archive=str(path))
        wait_for_state(endpoints, ("done",), settled=True)
        chunks = sorted(path.glob("frames/*/c.*"))
        (path / "log" / "journal.jsonl").write_bytes(b"")
        with pytest.raises(DaemonRequestError, match="the journal is empty, but chunk files"):
            client.request("resume", archive=str(path))
        assert sorted(path.glob("frames/*/c.*")) == chunks
        assert client.request("status")["state"] == "done"


def test_a_disk_full_at_the_close_finishes_the_session_naming_path_and_space(
    config, rig, tmp_path, monkeypatch
):
    # Every step is committed; only the close (array shapes, the closed record) needs space.
    write_atomic = _chunks.write_atomic
    closing = []

    def no_space_at_the_close(path, data, *, fsync):
        if closing:
            raise OSError(errno.ENOSPC, "No space left on device", str(path))
        return write_atomic(path, data, fsync=fsync)

    def trim(chunks, committed):
        closing.append(True)
        return trim_shapes(chunks, committed)

    trim_shapes = _chunks.StepChunks.trim
    monkeypatch.setattr(_chunks, "write_atomic", no_space_at_the_close)
    monkeypatch.setattr(_chunks.StepChunks, "trim", trim)
    path = tmp_path / "full.zarr"
    with running_daemon(config, rig) as endpoints, DaemonClient(endpoints) as client:
        client.request("submit", plan_toml=LAMP_PLAN, source="test", archive=str(path))
        ended = wait_for_state(endpoints, ("done", "failed", "paused"), settled=True)
    assert ended["state"] == "done"
    session = ended["session"]
    assert session["committed"] == session["steps"] and session["reason"] is None
    fault = session["fault"]
    assert (fault["device"], fault["operation"]) == ("archive", "close")
    assert f"{path}/frames/cam0/zarr.json: disk full while writing camera 'cam0'" in fault["detail"]
    assert "it needs about 0.00" in fault["detail"] and "MB free" in fault["detail"]
    assert "Errno" not in fault["detail"]
    closing.clear()
    with Archive.open(path) as archive:
        assert archive.committed_steps() == tuple(range(session["steps"]))
