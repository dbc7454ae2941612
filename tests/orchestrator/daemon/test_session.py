"""Whole sessions through the daemon's sockets with soft devices: full run, pause/resume,
abort, a device fault that pauses and is retried, on_fault="fail"."""

import time

import numpy as np
import pytest

from orchestrator.client import (
    DaemonClient,
    DaemonRequestError,
    follow,
    session_ended,
    wait_for_state,
)
from orchestrator.daemon import frame_formats
from rig.archive import Archive
from rig.plan import parse_plan
from rig.schedule import compile_plan
from tests.orchestrator.daemon.conftest import LAMP_PLAN, TINY_PLAN, running_daemon, running_workers
from tests.orchestrator.daemon.soft import soft_image


def _submit(client, plan_text, path):
    return client.request("submit", plan_toml=plan_text, source="test", archive=str(path))


def _check_archive(path, config, plan_text, rig=None):
    """Every step of the plan exactly once, frames as the soft cameras made them."""
    plan = parse_plan(plan_text)
    steps = compile_plan(plan, config).steps
    formats = frame_formats(config, scale=plan.resolution.scale)
    with Archive.open(path) as archive:
        assert archive.committed_steps() == tuple(range(len(steps)))
        table = archive.frame_table()
        for step in steps:
            record = archive.step_table()[step.index]
            assert record.kind == step.kind and record.cameras == step.cameras
            for camera in step.cameras:
                rows = table[(table["step"] == step.index) & (table["camera"] == camera)]
                assert sorted(rows["sub"]) == list(range(step.frames_per_camera))
            if step.kind == "btf":
                for camera in step.cameras:
                    for sub, exposure in enumerate(step.exposures_s):
                        expected = soft_image(
                            formats[camera], camera, *step.pose,
                            (step.source,), False, exposure,
                        )  # fmt: skip
                        np.testing.assert_array_equal(
                            archive.read_frame(step.index, camera, sub), expected
                        )
        return archive.frame_table(), {e.kind for e in archive.events()}


def test_full_session_with_workers(config, rig, tmp_path):
    path = tmp_path / "s.zarr"
    with running_daemon(config, rig) as endpoints, running_workers(endpoints, 2) as done:
        wait_for_state(endpoints, ("idle",))
        with DaemonClient(endpoints) as client:
            for _ in range(50):  # until the workers' hellos arrived
                if client.request("status")["workers"] == 2:
                    break
            events = []
            reply = _submit(client, TINY_PLAN, path)
            assert reply["state"] in ("homing", "running", "finishing", "done")
            events = list(follow(endpoints, until=session_ended, timeout_s=20))
            final = wait_for_state(endpoints, ("done",), settled=True)
    assert sum(done.values()) >= final["stream"]["processed"] > 0
    assert final["stream"]["not_streamed"] == 0
    assert rig.violations == []
    table, kinds = _check_archive(path, config, TINY_PLAN)
    assert {"session", "scan"} <= kinds
    telemetry = [e for e in events if e["topic"] == "telemetry"]
    assert telemetry and {"turntable_deg", "arc_deg", "step"} <= set(telemetry[-1])
    progress = [e for e in events if e["topic"] == "progress"]
    assert progress and progress[-1]["step"] == progress[-1]["steps"]
    assert all(e["eta_s"] >= 0 for e in progress)
    seqs = [e["seq"] for e in events if e["seq"] is not None]
    assert seqs == sorted(seqs) and len(set(seqs)) == len(seqs)
    # the subscription starts after the submit: the homing → running change may come first
    states = [e["to"] for e in events if e["topic"] == "state"]
    assert states[-2:] == ["finishing", "done"]
    with Archive.open(path) as archive:
        stats = archive.material["live/stats"]
        for camera in ("cam0", "cam2"):
            group = stats[camera]
            rows = table[table["camera"] == camera]
            assert group["step"].shape[0] == len(rows)  # every frame processed exactly once
            for step, sub, mean in zip(
                group["step"][:], group["sub"][:], group["mean"][:], strict=True
            ):
                image = archive.read_frame(int(step), camera, int(sub))
                np.testing.assert_allclose(mean, image.mean(axis=(0, 1)), rtol=1e-6)


def test_a_lamp_the_next_step_uses_stays_lit(config, rig, tmp_path):
    steps = compile_plan(parse_plan(LAMP_PLAN), config).steps
    assert len({s.source for s in steps}) == 1 < len(steps)  # one lamp for every step
    with running_daemon(config, rig) as endpoints, DaemonClient(endpoints) as client:
        _submit(client, LAMP_PLAN, tmp_path / "l.zarr")
        wait_for_state(endpoints, ("done",), settled=True)
    _check_archive(tmp_path / "l.zarr", config, LAMP_PLAN)
    assert [lit for lit in rig.lamp_switches if lit] == [frozenset({steps[0].source})]
    assert rig.violations == [] and rig.lamps_on == frozenset()


def test_pause_resume_and_abort(config, rig, tmp_path):
    rig.real_delay_s = 0.01  # slow enough to catch it running
    with running_daemon(config, rig) as endpoints, DaemonClient(endpoints) as client:
        _submit(client, LAMP_PLAN, tmp_path / "a.zarr")
        wait_for_state(endpoints, ("running",))
        paused = client.request("pause")
        assert paused["state"] == "paused"
        with pytest.raises(DaemonRequestError) as info:
            client.request("pause")
        assert info.value.code == "illegal_state" and "resume" in info.value.message
        committed = client.request("status")["session"]["committed"]
        time.sleep(0.2)
        assert client.request("status")["session"]["committed"] <= committed + 1
        client.request("resume")
        wait_for_state(endpoints, ("done",), settled=True)
        _check_archive(tmp_path / "a.zarr", config, LAMP_PLAN)

        # A second session, aborted while running: committed steps stay, no more come.
        _submit(client, LAMP_PLAN, tmp_path / "b.zarr")
        wait_for_state(endpoints, ("running",))
        client.request("abort")
        final = wait_for_state(endpoints, ("aborted",), settled=True)
        with pytest.raises(DaemonRequestError, match="illegal_state"):
            client.request("resume")
    steps = len(compile_plan(parse_plan(LAMP_PLAN), config).steps)
    with Archive.open(tmp_path / "b.zarr") as archive:
        assert len(archive.committed_steps()) < steps
        assert archive.committed_steps() == tuple(range(len(archive.committed_steps())))
    assert final["session"]["committed"] == len(archive.committed_steps())
    assert rig.lamps_on == frozenset() and rig.laser_on is False
    assert rig.violations == []


@pytest.mark.parametrize("where", ["turntable.wait", "arc.wait", "cam2.read"])
def test_device_fault_pauses_then_resume_retries_the_step(config, rig, tmp_path, where):
    rig.faults.arm(where, "drop" if where.endswith("read") else "stall")
    with running_daemon(config, rig) as endpoints, DaemonClient(endpoints) as client:
        _submit(client, LAMP_PLAN, tmp_path / "f.zarr")
        paused = wait_for_state(endpoints, ("paused",))
        fault = paused["session"]["fault"]
        device = where.split(".")[0]
        assert fault["device"] == device and fault["step"] == paused["session"]["step_index"]
        assert paused["session"]["committed"] == fault["step"]  # the failed step is not in
        assert rig.lamps_on == frozenset()  # lamps off while waiting for the user
        client.request("resume")
        wait_for_state(endpoints, ("done",), settled=True)
    _check_archive(tmp_path / "f.zarr", config, LAMP_PLAN)
    with Archive.open(tmp_path / "f.zarr") as archive:
        faults = archive.events("fault")
    assert [f.payload["device"] for f in faults] == [device]


def test_device_fault_fails_the_session_when_configured(config, rig, tmp_path):
    rig.faults.arm("lamps.switch", "dark")
    daemon = running_daemon(config, rig, on_fault="fail")
    with daemon as endpoints, DaemonClient(endpoints) as client:
        _submit(client, LAMP_PLAN, tmp_path / "x.zarr")
        failed = wait_for_state(endpoints, ("failed",), settled=True)
        assert "lamp bank" in failed["session"]["reason"]
        assert "stays dark" in failed["session"]["reason"]
        # The daemon goes on: the next session runs.
        _submit(client, LAMP_PLAN, tmp_path / "y.zarr")
        wait_for_state(endpoints, ("done",), settled=True)
    _check_archive(tmp_path / "y.zarr", config, LAMP_PLAN)


def test_the_rig_calibration_goes_into_the_archive(rig, tmp_path):
    from rig.calfile import CalibrationFile, LaserResult, write_calibration

    laser = LaserResult(angle_deg=44.9, angle_std_deg=0.01, residual_mm=0.0, heights=2)
    cal = write_calibration(CalibrationFile(laser={"mount0": laser}), tmp_path / "cal.toml")
    config = rig.config.model_copy(update={"calibration": str(cal)})
    with running_daemon(config, rig) as endpoints, DaemonClient(endpoints) as client:
        _submit(client, LAMP_PLAN, tmp_path / "s.zarr")
        wait_for_state(endpoints, ("done",), settled=True)
    with Archive.open(tmp_path / "s.zarr") as archive:
        assert archive.calibration_version == 1
        assert archive.calibration["laser"]["mount0"]["angle_deg"] == 44.9


def test_a_missing_calibration_file_refuses_the_submit_by_name(config, rig, tmp_path):
    missing = config.model_copy(update={"calibration": str(tmp_path / "none.toml")})
    with running_daemon(missing, rig) as endpoints, DaemonClient(endpoints) as client:
        with pytest.raises(DaemonRequestError, match=r"calibration file .*none\.toml"):
            _submit(client, LAMP_PLAN, tmp_path / "s.zarr")
        assert client.request("status")["state"] == "idle"  # the daemon goes on
