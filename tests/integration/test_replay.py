"""Replay: a session recorded against the simulated rig, run back through the daemon."""

from __future__ import annotations

import numpy as np
import pytest

from drivers.errors import DeviceError
from orchestrator import client
from orchestrator.daemon import ReplayDevices
from orchestrator.local import replay_local
from rig.archive import Archive
from rig.clock import VirtualClock
from sim.rig import SimulatedRig
from tests.integration.conftest import run_session

# Sessions, subprocesses or benches: the full tier only (make test), not make quick.
pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def recording(scene, tmp_path_factory):
    """One recorded session (module-wide; replays only read it)."""
    clock = VirtualClock()
    with SimulatedRig(scene, clock=clock) as sim:
        archive, status = run_session(sim, clock, tmp_path_factory.mktemp("recording"))
    assert status["state"] == "done", status
    return archive


def _frames(path):
    with Archive.open(path) as archive:
        table = archive.frame_table()
        return {
            (int(r["step"]), str(r["camera"]), int(r["sub"])): archive.read_frame(
                int(r["step"]), str(r["camera"]), int(r["sub"])
            )
            for r in table
        }, archive.step_table()


def _stats(path):
    with Archive.open(path) as archive:
        group = archive.material["live/stats"]
        return {cam: {k: group[cam][k][:] for k in ("step", "sub", "mean")} for cam in group}


def test_replay_reproduces_the_frames_steps_and_worker_results(recording, tmp_path):
    final = replay_local(recording, out=tmp_path / "replay.zarr", speed=None)
    assert final["state"] == "done", final
    frames, steps = _frames(recording)
    again, steps_again = _frames(tmp_path / "replay.zarr")
    assert again.keys() == frames.keys() and len(frames) == final["session"]["frames"]
    for key, image in frames.items():
        np.testing.assert_array_equal(again[key], image)
    assert [(s.kind, s.lamp, s.laser, s.actuators) for s in steps_again] == [
        (s.kind, s.lamp, s.laser, s.actuators) for s in steps
    ]
    stats, stats_again = _stats(recording), _stats(tmp_path / "replay.zarr")
    assert stats.keys() == stats_again.keys()
    for cam in stats:
        for name in ("step", "sub", "mean"):
            np.testing.assert_array_equal(stats_again[cam][name], stats[cam][name])


def test_paced_replay_takes_the_recorded_time_over_speed(recording, tmp_path):
    _, steps = _frames(recording)
    span = steps[-1].started_at - steps[0].started_at
    clock = VirtualClock()
    final = replay_local(recording, out=tmp_path / "paced.zarr", speed=0.5, clock=clock)
    assert final["state"] == "done", final
    assert clock.now() >= span / 0.5 - 1e-6


def test_replay_devices_refuse_what_the_recording_did_not_do(recording):
    _, steps = _frames(recording)
    first = steps[0]
    moved = first.actuators["turntable_deg"] + 5.0
    with Archive.open(recording) as source:
        devices = ReplayDevices(source, clock=VirtualClock())
        with pytest.raises(DeviceError, match=r"step 0: the plan moves turntable_deg"):
            devices.move(turntable_deg=moved, arc_deg=first.actuators["arc_deg"])
        devices.move(**first.actuators)
        other = "lamp9" if first.lamp != "lamp9" else "lamp0"
        with pytest.raises(DeviceError, match=rf"step 0: the plan lights lamp '{other}'"):
            devices.lamp(other, True)
        with pytest.raises(DeviceError, match=r"exposures"):
            devices.capture(first.cameras, [e * 2 for e in first.exposures_s])


def test_replay_of_an_unfinished_recording_fails_naming_the_missing_step(scene, tmp_path):
    clock = VirtualClock()
    lamp = scene.rig.light_arc.lamps[2].id
    with SimulatedRig(scene, clock=clock, faults={"lamp_bank": {"dead_lamps": [lamp]}}) as sim:

        def abort(endpoints, status):
            assert status["state"] == "paused", status
            client.abort(connect=endpoints)
            return client.wait_for_state(endpoints, ("aborted",), settled=True)

        partial, status = run_session(
            sim, clock, tmp_path, until_state=("paused", *client.TERMINAL_STATES), act=abort
        )
    committed = status["session"]["committed"]
    assert 0 < committed < status["session"]["steps"]
    final = replay_local(partial, out=tmp_path / "replay.zarr", speed=None)
    assert final["state"] == "failed"
    assert f"only {committed} committed step(s)" in final["session"]["reason"]
