"""UR arm kinematics: published zero pose, closed-form inverse against forward, limits."""

import numpy as np
import pytest
from hypothesis import assume, example, given
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from rig.errors import KinematicsError
from rig.ur_kinematics import UR_MODELS, Pose, forward, inverse, nearest_joints

UR5E = UR_MODELS["ur5e"]
FREE = np.tile([-2 * np.pi, 2 * np.pi], (6, 1))
joint_angles = st.lists(st.floats(-np.pi, np.pi), min_size=6, max_size=6).map(np.array)


def _same_angles(a, b) -> bool:
    return bool(np.all(np.abs(np.angle(np.exp(1j * (np.asarray(a) - b)))) < 1e-6))


@pytest.mark.parametrize("name", sorted(UR_MODELS))
def test_zero_joints_put_the_flange_at_the_published_place(name):
    # All joints at 0: the arm stretched out along -x; flange at (a2 + a3, -(d4 + d6), d1 - d5).
    m = UR_MODELS[name]
    t = forward(np.zeros(6), m)
    assert_allclose(t[:3, 3], [m.a[1] + m.a[2], -(m.d[3] + m.d[5]), m.d[0] - m.d[4]], atol=1e-12)
    assert_allclose(t[:3, :3], [[1, 0, 0], [0, 0, -1], [0, 1, 0]], atol=1e-12)  # Rx(90°)


def test_ur5e_zero_pose_in_millimetres():
    assert_allclose(forward(np.zeros(6))[:3, 3], [-0.8172, -0.2329, 0.0628], atol=1e-9)


@given(joint_angles)
def test_inverse_finds_the_joints_forward_came_from(q):
    assume(abs(np.sin(q[4])) > 1e-3)  # a straight wrist couples joints 4 and 6: below
    t = forward(q)
    solutions = inverse(t)
    assert 1 <= len(solutions) <= 8
    assert any(_same_angles(s, q) for s in solutions)
    for s in solutions:  # every solution reaches the pose
        assert_allclose(forward(s), t, atol=1e-6)


def test_a_straight_wrist_still_reaches_the_pose():
    q = np.radians([20.0, -60.0, 70.0, -30.0, 0.0, 40.0])  # joint 5 at 0: 4 and 6 add up
    solutions = inverse(forward(q))
    assert len(solutions) >= 1
    for s in solutions:
        assert_allclose(forward(s), forward(q), atol=1e-6)


def test_a_general_pose_has_eight_solutions():
    q = np.radians([30.0, -70.0, 80.0, -100.0, -80.0, 20.0])
    solutions = inverse(forward(q))
    assert len(solutions) == 8
    assert len({tuple(np.round(s, 6)) for s in solutions}) == 8


def test_out_of_reach_has_no_solution_and_the_error_names_the_pose():
    far = Pose((1.2, 0.0, 0.2), (np.pi, 0.0, 0.0))
    assert inverse(far.matrix()).shape == (0, 6)
    with pytest.raises(KinematicsError, match=r"\(1200\.0, 0\.0, 200\.0\) mm.*out of reach"):
        nearest_joints(far, np.zeros(6), limits_rad=FREE)


def test_nearest_picks_the_solution_closest_to_the_present_joints():
    q = np.radians([30.0, -70.0, 80.0, -100.0, -80.0, 20.0])
    pose = Pose.from_matrix(forward(q))
    assert_allclose(nearest_joints(pose, q + 0.05, limits_rad=FREE), q, atol=1e-9)
    # a whole turn away on the base: the same joint angle one turn on, nearest the present
    shifted = q.copy()
    shifted[0] -= 2 * np.pi
    assert_allclose(nearest_joints(pose, shifted, limits_rad=FREE), shifted, atol=1e-9)


def test_joint_limits_exclude_solutions_or_refuse_the_pose():
    q = np.radians([30.0, -70.0, 80.0, -100.0, -80.0, 20.0])
    pose = Pose.from_matrix(forward(q))
    limits = FREE.copy()
    limits[2] = [np.radians(-170), 0.0]  # elbow may only bend one way: the other branch
    chosen = nearest_joints(pose, q, limits_rad=limits)
    assert chosen[2] < 0
    assert_allclose(forward(chosen), forward(q), atol=1e-6)
    limits[0] = [np.radians(100), np.radians(120)]
    with pytest.raises(KinematicsError, match="outside the joint limits"):
        nearest_joints(pose, q, limits_rad=limits)


def test_the_tcp_offsets_the_flange():
    q = np.radians([10.0, -80.0, 90.0, -90.0, -90.0, 0.0])
    tcp = Pose((0.0, 0.0, 0.15), (0.0, 0.0, 0.0))
    tool = Pose.from_matrix(forward(q) @ tcp.matrix())
    assert_allclose(nearest_joints(tool, q, limits_rad=FREE, tcp=tcp), q, atol=1e-9)


@given(st.lists(st.floats(-3.0, 3.0), min_size=3, max_size=3))
@example([1.0, 2.951171875, 0.3984375])  # 0.00025 rad short of a half turn
def test_pose_matrix_round_trip(rotvec):
    pose = Pose((0.1, -0.2, 0.3), tuple(rotvec))
    assert_allclose(Pose.from_matrix(pose.matrix()).matrix(), pose.matrix(), atol=1e-9)


@pytest.mark.parametrize("axis", [(1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 1, 0), (1, -2, 3)])
def test_half_turns_keep_their_axis(axis):
    rotvec = np.pi * np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    pose = Pose((0.0, 0.0, 0.0), tuple(rotvec))
    assert_allclose(Pose.from_matrix(pose.matrix()).matrix(), pose.matrix(), atol=1e-9)


def test_a_pose_must_be_finite():
    with pytest.raises(KinematicsError, match="finite"):
        Pose((0.0, np.nan, 0.0), (0.0, 0.0, 0.0))


def test_urscript_pose_text():
    assert Pose((0.1, 0.0, -0.25), (0.0, 3.1416, 0.0)).script() == (
        "p[0.100000, 0.000000, -0.250000, 0.000000, 3.141600, 0.000000]"
    )
