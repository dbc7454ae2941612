"""The simulated Bonn lab: its arm, rail and lamp bank as peers, driven by the real drivers."""

import numpy as np
import pytest

from drivers import open_device
from rig import bonn
from rig.clock import VirtualClock
from rig.devices import Retry
from sim.rig import SimulatedRig
from sim.scene import load_scene

FAST = Retry(timeout_s=0.5, retries=2, backoff_s=0.01)


@pytest.fixture
def lab():
    clock = VirtualClock()
    scene = load_scene("examples/scenes/bumps.toml", kind="bonn")
    with SimulatedRig(scene, clock=clock) as sim:
        yield sim, sim.rig_config(), clock


def test_the_rail_is_a_configured_axis_on_its_drive_family(lab):
    sim, config, clock = lab
    assert sim.scene.rig.device_roles == ("arm", "rail", "lamp_bank")
    assert set(sim.peers) == {"arm", "rail", "lamp_bank"}
    rail = open_device("rail", config.bonn.rail, clock=clock)
    try:
        rail.home()
        rail.move_to(90.0)
        got = rail.wait_until_settled()
    finally:
        rail.close()
    assert got == pytest.approx(90.0, abs=0.1)
    assert sim.world.position("rail") == pytest.approx(90.0, abs=1e-6)


def test_the_arm_holds_the_plate_at_the_orientation_of_a_direction_pair(lab):
    _sim, config, clock = lab
    arm_section = config.bonn.arm.model_copy(
        update={"device": config.bonn.arm.device.model_copy(update={"retry": FAST})}
    )
    arm = open_device("arm", arm_section, clock=clock)
    try:
        arm.home()
        pose = bonn.inverse(config, (30.0, 40.0), (60.0, 200.0))
        arm.move_to(bonn.plate_tool_pose(config, pose.rotation))
        reached = arm.wait_until_settled()
    finally:
        arm.close()
    np.testing.assert_allclose(reached.matrix()[:3, :3], pose.rotation, atol=1e-3)
    view, light = bonn.forward(config, reached.matrix()[:3, :3], pose.rail_deg)
    np.testing.assert_allclose(view, (30.0, 40.0), atol=0.1)
    np.testing.assert_allclose(light, (60.0, 200.0), atol=0.1)
