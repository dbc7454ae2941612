"""The UR arm driver against the simulated controller, over real TCP sockets."""

import numpy as np
import pytest
from pydantic import BaseModel

from drivers.errors import DeviceError, DeviceFault, DeviceTimeout, MotionStalled
from drivers.interfaces import Positioner
from drivers.registry import open_device
from drivers.ur import UrArm
from rig.devices import ArmDevice, UrController
from rig.errors import KinematicsError
from rig.ur_kinematics import UR_MODELS, Pose, forward
from sim.peers.registry import start_peer
from tests.drivers.ur.conftest import device_of

pytestmark = pytest.mark.timeout(60)


def _offset(pose: Pose, dx_m: float, dz_m: float, rotvec) -> Pose:
    x, y, z = pose.position_m
    return Pose((x + dx_m, y, z + dz_m), tuple(rotvec))


def _pose_error(a: Pose, b: Pose) -> tuple[float, float]:
    """Position error (m) and rotation error (deg) between two poses."""
    ta, tb = a.matrix(), b.matrix()
    position = float(np.linalg.norm(ta[:3, 3] - tb[:3, 3]))
    cos = np.clip((np.trace(ta[:3, :3].T @ tb[:3, :3]) - 1) / 2, -1, 1)
    return position, float(np.degrees(np.arccos(cos)))


class ArmSection(BaseModel):
    """The part of a rig kind's arm section the registry reads: its device."""

    device: ArmDevice


# A sample orientation: tool tilted 30° from pointing straight down.
_TILTED = (0.0, np.pi * 5 / 6, 0.0)


def test_satisfies_the_interface(arm):
    assert isinstance(arm, Positioner)


def test_home_powers_on_and_releases_the_brakes(arm):
    assert arm.status().robot_mode == "POWER_OFF"
    arm.home()
    status = arm.status()
    assert (status.robot_mode, status.safety_status) == ("RUNNING", "NORMAL")
    assert status.program_state.startswith("STOPPED")


def test_move_reaches_the_pose_and_reads_it_back(ready_arm, controller, clock):
    start = ready_arm.pose()
    target = _offset(start, 0.08, -0.05, _TILTED)
    t0 = clock.now()
    ready_arm.move_to(target)
    reached = ready_arm.wait_until_settled()
    elapsed = clock.now() - t0
    position_m, angle_deg = _pose_error(reached, target)
    assert position_m < 1e-4 and angle_deg < 0.01
    # the controller's own forward kinematics of its joints agrees
    truth = Pose.from_matrix(forward(np.radians(controller.joints_deg()), UR_MODELS["ur5e"]))
    assert _pose_error(truth, target)[0] < 1e-4
    # the move took the profile time of the joint moving furthest
    moved_deg = np.max(np.abs(controller.joints_deg() - np.array([0, -90, 90, -90, -90, 0])))
    expected = float(ready_arm._joint_axis.move_time_s(moved_deg))
    assert expected - 1e-6 <= elapsed <= expected + 0.05
    assert ready_arm.joints_deg() == pytest.approx(controller.joints_deg(), abs=1e-6)


def test_the_arm_is_read_every_poll_s_of_the_config_while_it_moves(controller, clock):
    # A coarser state-read interval ends the wait on its grid: at most one poll_s late.
    arm = UrArm(device_of(controller, poll_s=0.25), clock=clock)
    try:
        arm.home()
        target = _offset(arm.pose(), 0.08, -0.05, _TILTED)
        t0 = clock.now()
        arm.move_to(target)
        arm.wait_until_settled()
        elapsed = clock.now() - t0
        moved_deg = np.max(np.abs(controller.joints_deg() - np.array([0, -90, 90, -90, -90, 0])))
        expected = float(arm._joint_axis.move_time_s(moved_deg))
    finally:
        arm.close()
    assert expected - 1e-6 <= elapsed <= expected + 0.25 + 1e-6
    assert elapsed / 0.25 == pytest.approx(round(elapsed / 0.25), abs=1e-6)


def test_the_tool_centre_point_is_sent_with_the_move(controller, clock):
    tcp = (0.0, 0.0, 0.12, 0.0, 0.0, 0.0)  # the sample plate 12 cm out from the flange
    arm = UrArm(device_of(controller, tcp=tcp), clock=clock)
    try:
        arm.home()
        target = _offset(arm.pose(), 0.0, 0.1, _TILTED)
        arm.move_to(target)
        reached = arm.wait_until_settled()
        assert _pose_error(reached, target)[0] < 1e-4
        flange = Pose.from_matrix(forward(np.radians(controller.joints_deg())))
        assert _pose_error(flange, target)[0] == pytest.approx(0.12, abs=1e-4)
    finally:
        arm.close()


def test_protective_stop_mid_move_names_the_arm_then_unlock_and_resume(
    ready_arm, controller, clock
):
    start = ready_arm.pose()
    target = _offset(start, -0.1, 0.05, _TILTED)
    controller.protective_stop(fraction=0.4)
    ready_arm.move_to(target)
    with pytest.raises(DeviceFault, match=r"^arm: move_to failed: protective stop at") as err:
        ready_arm.wait_until_settled()
    assert "unlock_protective_stop" in str(err.value)
    stopped = ready_arm.pose()
    # stopped part of the way: neither at the start nor at the target
    assert _pose_error(stopped, start)[0] > 0.01 and _pose_error(stopped, target)[0] > 0.01
    assert ready_arm.status().safety_status == "PROTECTIVE_STOP"
    t_stop = clock.now()
    ready_arm.unlock_protective_stop()  # refused for 5 s after the stop, retried
    assert clock.now() - t_stop >= 5.0 - 0.5
    assert ready_arm.status().safety_status == "NORMAL"
    ready_arm.move_to(target)
    assert _pose_error(ready_arm.wait_until_settled(), target)[0] < 1e-4


def test_an_unlock_the_controller_keeps_refusing_is_a_fault(make_peer, clock):
    controller = make_peer(faults={"unlock_delay_s": 30.0})
    arm = UrArm(device_of(controller, unlock_wait_s=2.0), clock=clock)
    try:
        arm.home()
        controller.protective_stop(fraction=0.5)
        arm.move_to(_offset(arm.pose(), 0.1, 0.0, _TILTED))
        with pytest.raises(DeviceFault):
            arm.wait_until_settled()
        with pytest.raises(DeviceFault, match=r"arm: unlock failed: .*refuses .*5s after"):
            arm.unlock_protective_stop()
    finally:
        arm.close()


def test_unreachable_pose_is_refused_before_anything_moves(ready_arm, controller):
    joints = controller.joints_deg()
    far = Pose((1.5, 0.2, 0.3), _TILTED)
    with pytest.raises(
        KinematicsError, match=r"^arm: cannot move to \(1500\.0, 200\.0, 300\.0\) mm"
    ):
        ready_arm.move_to(far)
    with pytest.raises(KinematicsError, match="out of reach"):
        ready_arm.check_reachable(far)
    assert controller.state.moves == 0
    assert controller.joints_deg() == pytest.approx(joints)


def test_a_pose_only_beyond_the_joint_limits_is_refused(controller, clock):
    limits = {"joint_min_deg": (-30.0, *[-360.0] * 5), "joint_max_deg": (30.0, *[360.0] * 5)}
    arm = UrArm(device_of(controller, **limits), clock=clock)
    try:
        behind = Pose((0.45, 0.2, 0.4), (np.pi, 0.0, 0.0))  # needs the base turned ~180°
        with pytest.raises(KinematicsError, match="outside the joint limits"):
            arm.check_reachable(behind)
    finally:
        arm.close()


def test_a_dropped_connection_mid_move_is_reconnected(ready_arm, controller):
    target = _offset(ready_arm.pose(), 0.05, 0.05, _TILTED)
    ready_arm.move_to(target)
    ready_arm._read_state("test")
    controller.drop_connections()
    assert _pose_error(ready_arm.wait_until_settled(), target)[0] < 1e-4
    assert ready_arm.status().robot_mode == "RUNNING"  # the dashboard reconnected too


def test_a_controller_gone_is_a_clear_error(ready_arm, controller):
    controller.stop()
    with pytest.raises(DeviceTimeout, match=r"^arm: pose failed: .*gave up after 3 tries"):
        ready_arm.pose()


def test_a_move_while_powered_off_names_the_cause(arm, controller):
    arm.move_to(_offset(arm.pose(), 0.05, 0.0, _TILTED))
    with pytest.raises(DeviceFault, match=r"robot mode POWER_OFF .*home"):
        arm.wait_until_settled()
    assert controller.errors and "cannot run a program" in controller.errors[-1]


def test_stop_ends_the_move_where_the_arm_is(ready_arm, controller, clock):
    start = ready_arm.pose()
    ready_arm.move_to(_offset(start, 0.1, 0.0, _TILTED))
    while not ready_arm.status().program_state.startswith("PLAYING"):
        clock.sleep(0.001)
    clock.sleep(0.5)
    ready_arm.stop()
    here = ready_arm.wait_until_settled()
    assert _pose_error(here, start)[0] > 1e-3
    clock.sleep(1.0)
    assert _pose_error(ready_arm.pose(), here)[0] < 1e-9


def test_stop_waits_until_the_controller_has_taken_it(ready_arm, controller, clock, monkeypatch):
    """A controller busy elsewhere takes the stopj only after some state packets (as a
    loaded machine's peer does): the wait returns where the arm came to rest, not
    where it was when the stopj left."""
    state = controller.state
    run_script, snapshot = state.run_script, state.snapshot
    held: list[str] = []

    def run_late(text: str) -> None:
        if text.startswith("stopj"):
            held.append(text)
        else:
            run_script(text)

    def snapshot_then_run_held() -> dict:
        if held and clock.now() >= stop_sent_at + 0.2:  # 0.2 s of virtual time later
            run_script(held.pop())
        return snapshot()

    monkeypatch.setattr(state, "run_script", run_late)
    monkeypatch.setattr(state, "snapshot", snapshot_then_run_held)
    start = ready_arm.pose()
    ready_arm.move_to(_offset(start, 0.1, 0.0, _TILTED))
    while not ready_arm.status().program_state.startswith("PLAYING"):
        clock.sleep(0.001)
    clock.sleep(0.3)
    stop_sent_at = clock.now()
    ready_arm.stop()
    here = ready_arm.wait_until_settled()
    assert not held
    clock.sleep(1.0)
    assert _pose_error(ready_arm.pose(), here)[0] < 1e-9


def test_one_owner_per_controller(arm, controller, clock):
    with pytest.raises(DeviceError, match="in use by process"):
        UrArm(device_of(controller), clock=clock)


def test_registry_opens_the_arm_on_its_peer(world, clock):
    section = ArmSection(device={"kind": "ur", "retry": {"timeout_s": 0.5}})
    peer = start_peer("arm", section, world, faults={"powered": True})
    try:
        arm = open_device("arm", peer.connect(section), clock=clock)
        try:
            assert isinstance(arm, UrArm)
            assert arm.status().robot_mode == "RUNNING"
        finally:
            arm.close()
    finally:
        peer.stop()


def test_a_fault_table_stops_the_nth_move_of_a_session(world, clock):
    section = ArmSection(device={"kind": "ur", "retry": {"timeout_s": 0.5}})
    faults = {"powered": True, "protective_stop_move": 2, "unlock_delay_s": 0.0}
    peer = start_peer("arm", section, world, faults=faults)
    arm = open_device("arm", peer.connect(section), clock=clock)
    try:
        start = arm.pose()
        targets = [_offset(start, 0.05 * i, 0.0, _TILTED) for i in (1, 2, 3)]
        arm.move_to(targets[0])
        arm.wait_until_settled()
        arm.move_to(targets[1])
        with pytest.raises(DeviceFault, match="protective stop"):
            arm.wait_until_settled()
        arm.unlock_protective_stop()
        for target in targets[1:]:  # the interrupted move again, then the session goes on
            arm.move_to(target)
            assert _pose_error(arm.wait_until_settled(), target)[0] < 1e-4
    finally:
        arm.close()
        peer.stop()


def test_a_move_the_controller_refuses_is_a_stall_naming_both_poses(make_peer, clock):
    # the controller's own joint limits are tighter than the config says: it refuses the move
    tight = UrController(joint_min_deg=(-10.0, *[-360.0] * 5), joint_max_deg=(10.0, *[360.0] * 5))
    controller = make_peer(device=tight, faults={"powered": True})
    arm = UrArm(device_of(controller), clock=clock)
    try:
        target = Pose((0.2, -0.45, 0.4), _TILTED)  # the base turned by about 90°
        arm.move_to(target)
        with pytest.raises(MotionStalled, match=r"ended the move at .* short of \(200\.0, -450\.0"):
            arm.wait_until_settled()
        assert "joint 1 target beyond its limit" in controller.errors[-1]
    finally:
        arm.close()
