"""A Bonn lab session end to end: a reduced plan through the daemon and the real drivers
(UR arm, Dynamixel rail, Modbus lamp bank, camera) against the simulated lab, every pair
captured once, its frames registered against the simulator's truth."""

from __future__ import annotations

import numpy as np
import pytest

from orchestrator import client
from orchestrator.daemon import run_local
from processing.offline import BtfStage, run_stages
from processing.registration import marker_corners_mm, register_frame
from rig import bonn
from rig.archive import Archive
from rig.clock import VirtualClock
from rig.geometry import angular_distance_deg, direction_vector
from rig.material import read_material
from rig.ur_kinematics import Pose
from sim.rig import SimulatedRig
from tests.integration.conftest import run_session
from tests.sim.bonn_registration import bonn_scene

# Sessions, subprocesses or benches: the full tier only (make test), not make quick.
pytestmark = pytest.mark.slow

PLAN = """
[sample]
name = "bonn"
[captures.btf]
views = [[0, 0], [34, 150]]
lights = [[34, 90], [51, 200], [17, 0]]
[exposure]
exposure_s = 0.05
"""


def test_a_reduced_plan_runs_on_the_bonn_lab_and_registers(tmp_path):
    (tmp_path / "plan.toml").write_text(PLAN)
    clock = VirtualClock()
    with SimulatedRig(bonn_scene(), clock=clock) as sim:
        config = sim.rig_config()
        final = run_local(
            tmp_path / "plan.toml", config, archive=tmp_path / "s.zarr", clock=clock
        )
        rig = sim.scene.rig
    assert final["state"] == "done", final
    with Archive.open(tmp_path / "s.zarr") as archive:
        steps = archive.step_table()
        frames = {s.index: archive.read_frame(s.index, "cam0", 0) for s in steps}
    wanted = {(v, lt) for v in ((0.0, 0.0), (34.0, 150.0))
              for lt in ((34.0, 90.0), (51.0, 200.0), (17.0, 0.0))}  # fmt: skip
    assert len(steps) == len(wanted) == 6  # every pair once
    reprojection = []
    for step in steps:
        view, light = step.views_deg["cam0"], step.light_deg
        match = [
            (v, lt) for v, lt in wanted
            if angular_distance_deg(direction_vector(*v), direction_vector(*view)) < 0.1
            and angular_distance_deg(direction_vector(*lt), direction_vector(*light)) < 0.1
        ]  # fmt: skip
        assert len(match) == 1, (view, light)
        wanted.discard(match[0])
        assert set(step.actuators) >= {"rail_deg", "tool_rx_deg"}
        # register the archived frame with the camera where the recorded actuators put it:
        # the plate turned as the arm's tool (the lab's axes are the arm base's), the rail
        a = step.actuators
        tool = Pose((0.0, 0.0, 0.0), tuple(np.radians([a[f"tool_r{c}_deg"] for c in "xyz"])))
        camera = bonn.camera_model(rig, "cam0", tool.matrix()[:3, :3], a["rail_deg"])
        result = register_frame(frames[step.index], rig.holder, size=64, camera=camera)
        assert result.valid, (view, light, result.reason)
        plate = marker_corners_mm(rig.holder)[result.detection.ids].reshape(-1, 2)
        projected, _ = camera.project(np.column_stack([plate, np.zeros(len(plate))]))
        found = result.detection.corners_px.reshape(-1, 2)
        assert np.linalg.norm(found - projected, axis=1).mean() < 0.3
        reprojection.append(result.homography.mean_reprojection_px)
    assert not wanted
    assert np.mean(reprojection) < 0.2, reprojection
    # `rig process --stages btf`: one view slot per planned view, three lights each
    run_stages(tmp_path / "s.zarr", [BtfStage(size=32, components=2)])
    material = read_material(tmp_path / "s.zarr")
    assert material.btf_slot_valid.tolist() == [True, True]
    got = direction_vector(*np.asarray(material.btf.view_dirs_deg, np.float64).T)
    for want in ((0.0, 0.0), (34.0, 150.0)):
        assert angular_distance_deg(got, direction_vector(*want)).min() < 0.1


def test_a_protective_stop_pauses_naming_the_arm_and_resume_finishes(tmp_path):
    clock = VirtualClock()
    faults = {"arm": {"protective_stop_move": 3, "unlock_delay_s": 1.0}}
    with SimulatedRig(bonn_scene(), clock=clock, faults=faults) as sim:

        def resume(endpoints, status):
            assert status["state"] == "paused", status
            fault = status["session"]["fault"]
            assert "arm" in fault["device"] and "protective stop" in fault["detail"], fault
            client.resume(connect=endpoints)
            return client.wait_for_state(
                endpoints, client.TERMINAL_STATES, settled=True, timeout_s=120
            )

        archive, status = run_session(
            sim, clock, tmp_path, PLAN, until_state=("paused", *client.TERMINAL_STATES),
            act=resume,
        )  # fmt: skip
    assert status["state"] == "done", status
    with Archive.open(archive) as stored:
        assert stored.committed_steps() == tuple(range(6))  # every step exactly once
        assert len(stored.frame_table()) == 6


def test_a_plan_with_an_unreachable_pair_is_refused_before_the_session_starts(tmp_path):
    clock = VirtualClock()
    scene = bonn_scene()
    narrow = scene.rig.bonn.arm.model_copy(update={"max_tilt_deg": 20.0})
    (tmp_path / "plan.toml").write_text(PLAN)
    with SimulatedRig(scene, clock=clock) as sim:
        config = sim.rig_config()
        config = config.model_copy(
            update={"bonn": config.bonn.model_copy(update={"arm": narrow.model_copy(
                update={"device": config.bonn.arm.device})})}
        )  # fmt: skip
        with pytest.raises(client.DaemonRequestError, match=r"plan_invalid .*\n.*captures.btf: "
                           r"view \(0°, 0°\), light \(17°, 0°\): the plate would tilt 28.0° "
                           r"from home, past the arm's max_tilt_deg 20°"):
            run_local(tmp_path / "plan.toml", config, archive=tmp_path / "s.zarr", clock=clock)
        assert sim.world.position("rail") == 0.0  # nothing moved
    assert not (tmp_path / "s.zarr").exists()
