"""Whole sessions with the real drivers against the simulated rig's peers.

The daemon opens Modbus, Dynamixel, NXT and camera drivers from the rig config
that ``SimulatedRig`` writes; nothing in between is soft. Each archived frame
is checked against the simulator's own render of the state the step recorded,
so a wrong lamp, a missed move or a stale frame fails the test.
"""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest

from orchestrator import client
from rig.archive import Archive
from rig.clock import VirtualClock
from rig.errors import ConfigError
from sim.rig import SimulatedRig
from sim.scene import scene_from_dict
from sim.world import WorldSnapshot
from tests.integration.conftest import run_session

# Sessions, subprocesses or benches: the full tier only (make test), not make quick.
pytestmark = pytest.mark.slow


def _snapshot(record):
    return WorldSnapshot(
        t=0.0,
        turntable_deg=record.actuators["turntable_deg"],
        arc_deg=record.actuators["arc_deg"],
        lamps_on=frozenset({record.lamp}) if record.lamp else frozenset(),
        laser_on=False,
        laser_tilt_deg=0.0,
        laser_mount=0,
    )


def test_full_session_frames_are_what_the_simulator_renders(scene, tmp_path):
    clock = VirtualClock()
    with SimulatedRig(scene, clock=clock) as sim:
        archive, status = run_session(sim, clock, tmp_path)
        assert status["state"] == "done", status
        with Archive.open(archive) as arch:
            steps = arch.step_table()
            assert arch.committed_steps() == tuple(range(status["session"]["steps"]))
            kinds = {r.kind for r in steps}
            assert kinds == {"ps", "btf", "mdf"}
            checked = 0
            for record in steps:
                if record.kind == "mdf":
                    continue
                for camera in record.cameras:
                    for sub, exposure in enumerate(record.exposures_s):
                        got = arch.read_frame(record.index, camera, sub)
                        want = sim.simulator.render(camera, _snapshot(record), exposure).image
                        assert got.shape == want.shape
                        # the recorded actuators are the drivers' read-back, quantised
                        # to encoder ticks: a few DN at silhouette edges, no more
                        diff = np.abs(got.astype(np.int32) - want.astype(np.int32))
                        assert np.mean(diff) < 0.5, (record.index, camera, np.mean(diff))
                        checked += 1
            assert checked >= 5
            # the same frame under another lamp differs: the check above can fail
            ps = [r for r in steps if r.kind == "ps"]
            a, b = ps[0], ps[1]
            other = sim.simulator.render(a.cameras[0], _snapshot(b), a.exposures_s[0]).image
            frame = arch.read_frame(a.index, a.cameras[0], 0)
            assert np.mean(np.abs(frame.astype(np.int32) - other.astype(np.int32))) > 2.0


def _frames(archive):
    with Archive.open(archive) as arch:
        return len(arch.frame_table()), arch.committed_steps()


def test_dropped_and_corrupt_frames_are_recaptured(scene, tmp_path):
    clock = VirtualClock()
    faults = {"cameras": {"dropped_frames": 1, "corrupt_frames": 1}}
    with SimulatedRig(scene, clock=clock, faults=faults) as sim:
        archive, status = run_session(sim, clock, tmp_path)
    assert status["state"] == "done", status
    n_frames, committed = _frames(archive)
    assert n_frames == status["session"]["frames"]
    assert committed == tuple(range(status["session"]["steps"]))


def test_dead_lamp_pauses_the_session_and_resume_retries_the_step(scene, tmp_path):
    clock = VirtualClock()
    lamp = scene.rig.light_arc.lamps[2].id  # θ = 30°: lights the ps and btf steps
    with SimulatedRig(scene, clock=clock, faults={"lamp_bank": {"dead_lamps": [lamp]}}) as sim:

        def replace_bulb_and_resume(endpoints, status):
            assert status["state"] == "paused", status
            fault = status["session"]["fault"]
            assert "lamp" in fault["device"] and lamp in fault["detail"], fault
            sim.peers["lamp_bank"].revive_lamp(lamp)
            client.resume(connect=endpoints)
            return client.wait_for_state(
                endpoints, client.TERMINAL_STATES, settled=True, timeout_s=60
            )

        archive, status = run_session(
            sim, clock, tmp_path, until_state=("paused", *client.TERMINAL_STATES),
            act=replace_bulb_and_resume,
        )  # fmt: skip
    assert status["state"] == "done", status
    n_frames, committed = _frames(archive)
    assert committed == tuple(range(status["session"]["steps"]))
    assert n_frames == status["session"]["frames"]
    assert n_frames == status["session"]["frames"]


def test_drive_fault_while_homing_fails_the_session_naming_the_drive(scene, tmp_path):
    clock = VirtualClock()
    with SimulatedRig(scene, clock=clock, faults={"turntable": {"drive_fault": True}}) as sim:
        archive, status = run_session(sim, clock, tmp_path)
    assert status["state"] == "failed"
    assert "turntable" in status["session"]["reason"], status["session"]
    assert _frames(archive) == (0, ())


def test_stalled_turntable_pauses_naming_it_and_resume_finishes(scene, tmp_path):
    clock = VirtualClock()
    with SimulatedRig(scene, clock=clock) as sim:
        sim.peers["turntable"].set_stall(0.5)  # every move stops halfway

        def unjam_and_resume(endpoints, status):
            assert status["state"] == "paused", status
            fault = status["session"]["fault"]
            assert "turntable" in fault["device"], fault
            sim.peers["turntable"].set_stall(None)
            client.resume(connect=endpoints)
            return client.wait_for_state(
                endpoints, client.TERMINAL_STATES, settled=True, timeout_s=60
            )

        archive, status = run_session(
            sim, clock, tmp_path, until_state=("paused", *client.TERMINAL_STATES),
            act=unjam_and_resume,
        )  # fmt: skip
    assert status["state"] == "done", status
    n_frames, committed = _frames(archive)
    assert committed == tuple(range(status["session"]["steps"]))
    assert n_frames == status["session"]["frames"]


def test_scene_fault_tables_are_injected_and_bad_peers_refused(tmp_path):
    scene = tomllib.loads(Path("examples/scenes/bumps.toml").read_text())
    scene["render"]["scale"] = 0.1
    scene["faults"] = {"laser": {"battery_mv": 6000}}
    with SimulatedRig(scene_from_dict(scene), clock=VirtualClock()) as sim:
        assert sim.peers["laser"].brick.faults.battery_mv == 6000
    scene["faults"] = {"toaster": {"burn": True}}
    with pytest.raises(ConfigError, match=r"unknown peer\(s\) \['toaster'\]; valid are"):
        SimulatedRig(scene_from_dict(scene), clock=VirtualClock())


TIMED_PLAN = """
[sample]
name = "timed"
[exposure]
exposure_s = 0.02
hdr_brackets = [1.0, 4.0]
""" + "".join(
    f'[[captures.fixed]]\nturntable_deg = 0\nlamp = "{lamp}"\n'
    'cameras = ["cam0", "cam1", "cam2", "cam3"]\n'
    for lamp in ("lamp2", "lamp4", "lamp6")
)


def test_cameras_fired_together_take_the_time_of_one(scene, tmp_path):
    """Steps at one position, through the real drivers and peers on virtual time: each
    step lasts lamp on + off and, per exposure, exposure + one readout (not four)."""
    from rig.plan import load_plan
    from rig.schedule import compile_plan
    from rig.timing import step_timing

    clock = VirtualClock()
    with SimulatedRig(scene, clock=clock) as sim:
        archive, status = run_session(sim, clock, tmp_path, TIMED_PLAN)
        config = sim.rig_config()
    assert status["state"] == "done", status
    with Archive.open(archive) as arch:
        started = [r.started_at for r in arch.step_table()]
    steps = compile_plan(load_plan(tmp_path / "plan.toml"), config).steps
    modelled = step_timing(config, steps[1], (0.0, 0.0)).total_s
    assert modelled == pytest.approx(0.1 + 0.02 + 0.08 + 2 * config.camera("cam0").readout_s)
    assert np.diff(started)[1:] == pytest.approx([modelled], rel=1e-9)
