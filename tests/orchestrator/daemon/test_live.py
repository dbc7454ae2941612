"""The live results' writer: on disk while the session runs, bounded, safe after a crash."""

from __future__ import annotations

import time

import numpy as np
import pytest
import zarr

from orchestrator.daemon.live import LiveWriter


@pytest.fixture
def material(tmp_path):
    return zarr.open_group(tmp_path / "material", mode="w", zarr_format=3)


def _texture(step: int) -> np.ndarray:
    return np.full((8, 8, 3), step, np.float32)


def _result(step: int, sub: int = 0, camera: str = "cam0") -> tuple[dict, dict]:
    header = {"step": step, "sub": sub, "camera": camera}
    arrays = {"register.texture": _texture(step), "register.reason": np.uint8(step % 3)}
    return header, {**arrays, "stats.mean": np.array([step, step + 0.5], np.float32)}


def _rows_on_disk(material, path: str) -> int:
    try:
        return material[path]["step"].shape[0]
    except KeyError:
        return 0


def test_results_reach_the_archive_while_the_session_runs(material):
    writer = LiveWriter(material)
    try:
        for step in range(3):
            writer.append(*_result(step))
        deadline = time.monotonic() + 10
        while _rows_on_disk(material, "live/register/cam0") < 3:  # no close, no drain
            assert time.monotonic() < deadline, "the results never reached the disk"
            time.sleep(0.05)
    finally:
        writer.close()
    register = material["live/register/cam0"]
    np.testing.assert_array_equal(register["step"][:], [0, 1, 2])
    np.testing.assert_array_equal(register["texture"][2], _texture(2))
    np.testing.assert_array_equal(register["reason"][:], [0, 1, 2])
    np.testing.assert_array_equal(material["live/stats/cam0/mean"][1], [1.0, 1.5])
    assert writer.frames == 3 and writer.take_errors() == []


def test_a_batch_a_crash_cut_short_is_dropped_and_the_session_goes_on(material):
    first = LiveWriter(material)
    for step in range(2):
        first.append(*_result(step))
    first.close()
    group = material["live/register/cam0"]
    group["texture"].append(_texture(9)[np.newaxis])  # the crash came before sub and step
    writer = LiveWriter(material)
    writer.append(*_result(2))
    writer.close()
    np.testing.assert_array_equal(group["step"][:], [0, 1, 2])
    assert group["texture"].shape[0] == group["sub"].shape[0] == 3
    np.testing.assert_array_equal(group["texture"][2], _texture(2))  # not the torn row


def test_a_backlog_stops_new_frames_until_written(material):
    writer = LiveWriter(material, max_backlog_bytes=500)
    try:
        writer.append(*_result(0))  # a texture of 8·8·3·4 = 768 bytes
        assert writer.backlogged  # written within the second: the batch is not full
    finally:
        writer.close()
    assert not writer.backlogged
    assert _rows_on_disk(material, "live/register/cam0") == 1


def test_a_stage_that_changes_its_arrays_is_reported_not_fatal(material):
    writer = LiveWriter(material)
    header, arrays = _result(0)
    writer.append(header, arrays)
    writer.append({**header, "step": 1}, {"register.texture": _texture(1)})  # no reason
    writer.append({**header, "camera": "cam1"}, arrays)
    writer.close()
    errors = writer.take_errors()
    assert len(errors) == 1 and "live/register/cam0" in errors[0] and "same arrays" in errors[0]
    assert _rows_on_disk(material, "live/register/cam1") == 1
    assert _rows_on_disk(material, "live/stats/cam0") == 1


def test_a_session_behind_a_slow_disk_waits_and_loses_nothing(config, rig, tmp_path, monkeypatch):
    from orchestrator import daemon
    from orchestrator.client import DaemonClient, wait_for_state
    from rig.archive import Archive
    from tests.orchestrator.daemon.conftest import LAMP_PLAN, running_daemon, running_workers

    class Tiny(LiveWriter):  # every result is more than the disk may lag behind
        def __init__(self, material):
            super().__init__(material, max_backlog_bytes=1)

    monkeypatch.setattr(daemon.relay, "LiveWriter", Tiny)
    path = tmp_path / "slow.zarr"
    with running_daemon(config, rig) as endpoints, running_workers(endpoints, n=1):
        with DaemonClient(endpoints) as client:
            client.request("submit", plan_toml=LAMP_PLAN, archive=str(path))
        done = wait_for_state(endpoints, ("done",), settled=True, timeout_s=120)
    assert done["stream"]["processed"] == done["session"]["frames"]
    with Archive.open(path) as archive:
        stats = archive.material["live/stats"]
        rows = sum(stats[camera]["step"].shape[0] for camera in stats.group_keys())
    assert rows == done["session"]["frames"]
