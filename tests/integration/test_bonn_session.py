"""A Bonn lab session end to end: a reduced plan through the daemon and the real drivers
(UR arm, Dynamixel rail, Modbus lamp bank, camera) against the simulated lab, every pair
captured once, its frames registered against the simulator's truth."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose
from typer.testing import CliRunner

from orchestrator import client
from orchestrator.cli import app
from orchestrator.local import run_local
from processing.offline import BtfStage, run_stages
from processing.registration import marker_corners_mm, register_frame
from rig import bonn
from rig.archive import Archive
from rig.clock import VirtualClock
from rig.geometry import angular_distance_deg, direction_vector
from rig.material import read_material
from rig.ur_kinematics import Pose
from sim.rig import SimulatedRig
from studies.bonn_registration import bonn_scene
from tests.integration.conftest import run_session

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
        final = run_local(tmp_path / "plan.toml", config, archive=tmp_path / "s.zarr", clock=clock)
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


RETRO_PLAN = """
[sample]
name = "bonn-retro"
[captures.ps]
lights = {theta_deg = 45, count = 3}
[captures.btf]
views = [[0, 0], [34, 150]]
lights = [[0, 0], [34, 150], [51, 200]]
[exposure]
exposure_s = 0.05
"""


def test_a_session_with_retro_pairs_goes_through_ps_btf_and_view(tmp_path):
    # the lab's own lamp: near (a point 2 m out), as examples/rigs/bonn.toml has it
    scene = bonn_scene(scale=0.25, supersample=1, lamp_kind="point")
    (tmp_path / "plan.toml").write_text(RETRO_PLAN)
    clock = VirtualClock()
    with SimulatedRig(scene, clock=clock) as sim:
        archive = tmp_path / "s.zarr"
        final = run_local(tmp_path / "plan.toml", sim.rig_config(), archive=archive, clock=clock)
    assert final["state"] == "done", final
    runner = CliRunner()
    result = runner.invoke(app, ["process", str(archive), "--stages", "ps,btf", "--size", "32"])
    assert result.exit_code == 0, result.output
    material = read_material(archive)
    # ps: the near lamp placed by each step's plate rotation; the sample is flat
    (ps,) = material.ps.values()
    assert ps.valid.all()
    tilt = np.degrees(np.arccos(np.clip(ps.normals[..., 2], -1, 1)))
    assert np.percentile(tilt, 95) < 3.0, np.percentile(tilt, 95)  # measured 2.2°
    mean = ps.normals.reshape(-1, 3).mean(axis=0)  # a misplaced lamp would tilt them all
    assert np.degrees(np.arccos(mean[2] / np.linalg.norm(mean))) < 0.2  # measured 0.03°
    # btf: the plan's grid, each retro cell filled by the capture the rail's end allowed,
    # listed with the directions it was measured at (each 5° off the cell's, 10° apart)
    views, lights = material.btf.view_dirs_deg, material.btf.light_dirs_deg
    assert material.btf_slot_valid.all() and views.shape == (2, 2) and lights.shape == (3, 2)
    with Archive.open(archive) as stored:
        displaced = stored.material["btf"].attrs["displaced"]
    cells = {(d[0], d[1]) for d in displaced}
    retro = {(j, i) for j in range(2) for i in range(3)
             if angular_distance_deg(direction_vector(*views[j]),
                                     direction_vector(*lights[i])) < 0.1}  # fmt: skip
    assert cells == retro and len(retro) == 2
    for slot, light, _, _, *measured in displaced:
        view_off = angular_distance_deg(direction_vector(*measured[:2]),
                                        direction_vector(*views[slot]))  # fmt: skip
        light_off = angular_distance_deg(direction_vector(*measured[2:]),
                                         direction_vector(*lights[light]))  # fmt: skip
        assert_allclose([view_off, light_off], [5.0, 5.0], atol=0.05)
    image = tmp_path / "view.png"
    result = runner.invoke(app, ["view", str(archive), "--mesh", "plane", "--size", "64x48",
                                 "--out", str(image)])  # fmt: skip
    assert result.exit_code == 0, result.output
    assert image.stat().st_size > 0


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
        with pytest.raises(
            client.DaemonRequestError,
            match=r"plan_invalid .*\n.*captures.btf: "
            r"view \(0°, 0°\), light \(17°, 0°\): the plate would tilt 28.0° "
            r"from home, past the arm's max_tilt_deg 20°",
        ):
            run_local(tmp_path / "plan.toml", config, archive=tmp_path / "s.zarr", clock=clock)
        assert sim.world.position("rail") == 0.0  # nothing moved
    assert not (tmp_path / "s.zarr").exists()
