"""The Bonn lab's kinematics and plans: plate orientation + rail ↔ sample-frame directions."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from rig import bonn
from rig.config import RigConfig
from rig.errors import KinematicsError, PlanError
from rig.geometry import angular_distance_deg, direction_angles, direction_vector
from rig.plan import parse_plan
from rig.schedule import compile_plan
from tests.budgets import scaled
from tests.rig.bonn_records import recorded_actuators


def _lab(**section):
    return RigConfig.model_validate({"kind": "bonn", "bonn": section})


def _close(got, want, tol_deg=1e-6):
    err = angular_distance_deg(direction_vector(*got), direction_vector(*want))
    assert err < tol_deg, (got, want, err)


@pytest.mark.parametrize(
    ("view", "light"),
    [((0.0, 0.0), (45.0, 30.0)), ((60.0, 200.0), (30.0, 10.0)), ((85.0, 0.0), (85.0, 180.0)),
     ((17.0, 300.0), (0.0, 0.0)), ((51.0, 120.0), (68.0, 126.0))],
)  # fmt: skip
def test_the_inverse_reaches_the_pair_and_forward_reads_it_back(view, light):
    config = _lab()
    pose = bonn.inverse(config, view, light)
    assert pose.view_residual_deg < 1e-6 and pose.light_residual_deg < 1e-6
    got_view, got_light = bonn.forward(config, pose.rotation, pose.rail_deg)
    _close(got_view, view)
    _close(got_light, light)
    np.testing.assert_allclose(pose.rotation.T @ pose.rotation, np.eye(3), atol=1e-12)
    assert np.linalg.det(pose.rotation) == pytest.approx(1.0)
    # the rail angle is the angle between view and light
    want = angular_distance_deg(direction_vector(*view), direction_vector(*light))
    assert pose.rail_deg == pytest.approx(want)


def test_the_arm_joints_hold_the_plate_at_the_orientation():
    from rig.ur_kinematics import UR_MODELS, forward

    config = _lab()
    pose = bonn.inverse(config, (30.0, 40.0), (60.0, 200.0))
    device = config.bonn.arm.device
    flange = forward(pose.joints_rad, UR_MODELS[device.model])
    np.testing.assert_allclose(flange[:3, :3], pose.rotation, atol=1e-9)
    # the plate centre (TCP, 50 mm out along the normal) is at the lab origin
    centre_in_base = flange[:3, 3] + flange[:3, 2] * device.tcp[2]
    np.testing.assert_allclose(centre_in_base * 1000, -np.array(config.bonn.arm.base_mm), atol=1e-6)


def test_a_view_next_to_the_light_leaves_an_even_residual_at_the_rail_end():
    config = _lab()
    pose = bonn.inverse(config, (34.0, 30.0), (34.0, 30.0))  # the camera would block the lamp
    assert pose.rail_deg == config.bonn.rail.axis.min_deg
    np.testing.assert_allclose(pose.view_residual_deg, 5.0, atol=1e-9)
    np.testing.assert_allclose(pose.light_residual_deg, 5.0, atol=1e-9)


def test_an_orientation_past_the_tilt_limit_is_refused_naming_the_pair():
    config = _lab(arm={"max_tilt_deg": 30.0})
    with pytest.raises(
        KinematicsError,
        match=r"view \(0°, 0°\), light \(80°, 180°\): the plate "
        r"would tilt [0-9.]+° from home, past the arm's max_tilt_deg 30°",
    ):
        bonn.inverse(config, (0.0, 0.0), (80.0, 180.0))


def test_an_orientation_outside_the_joint_limits_is_refused_naming_the_pair():
    device = {"kind": "ur", "tcp": [0, 0, 0.05, 0, 0, 0], "joint_min_deg": [-10] * 6,
              "joint_max_deg": [10] * 6}  # fmt: skip
    config = _lab(arm={"device": device})
    pair = "view (30°, 0°), light (30°, 180°)"
    with pytest.raises(
        KinematicsError,
        match=r"view \(30°, 0°\), light \(30°, 180°\): ur5e: "
        r"the pose .* reachable only outside the joint limits",
    ):
        bonn.arm_joints(config, bonn.home_rotation(config), pair=pair)


PLAN = """
[sample]
name = "s"
[captures.btf]
views = [[0, 0], [30, 0], [30, 120], [60, 240]]
lights = {theta_deg = 45, count = 6}
"""


def test_a_plan_compiles_to_one_step_per_pair_ordered_no_slower_than_its_own_order():
    schedule = compile_plan(parse_plan(PLAN), _lab())
    assert len(schedule.steps) == schedule.pairs == 24
    pairs = {(s.shots[0].view_deg, s.shots[0].light_deg) for s in schedule.steps}
    assert len(pairs) == 24
    assert schedule.estimate.total_s <= schedule.naive_estimate.total_s
    assert schedule.estimate.frames == 24 and schedule.estimate.motion_s > 0
    # the Wang rig fires its cameras together: fewer steps for the same pairs
    wang = compile_plan(parse_plan(PLAN), RigConfig())
    assert len(wang.steps) < len(schedule.steps)


def test_a_plan_with_unreachable_pairs_is_refused_before_anything_moves():
    with pytest.raises(PlanError) as err:
        compile_plan(parse_plan(PLAN), _lab(arm={"max_tilt_deg": 40.0}))
    text = str(err.value)
    assert "captures.btf: view (" in text and "past the arm's max_tilt_deg 40°" in text
    plan = PLAN + "[captures.mdf]\nviews = [[0, 0]]\nlaser_locations = [[45, 0]]\n"
    with pytest.raises(PlanError, match=r"captures.mdf: the Bonn lab has no laser unit"):
        compile_plan(parse_plan(plan), _lab())


def test_the_tour_beats_a_plan_order_that_jumps_about():
    plan = parse_plan(
        '[sample]\nname = "s"\n[captures.btf]\nviews = [[30, 0], [30, 180], [30, 90]]\n'
        "lights = [[45, 0], [45, 180], [45, 60], [45, 240], [45, 120], [45, 300]]\n"
    )
    schedule = compile_plan(plan, _lab())
    assert schedule.estimate.total_s < 0.9 * schedule.naive_estimate.total_s, (
        schedule.estimate.total_s,
        schedule.naive_estimate.total_s,
    )


@scaled(2 / 3)
@given(
    st.floats(0, 85), st.floats(0, 360), st.floats(0, 85), st.floats(0, 360),
)  # fmt: skip
def test_every_pair_round_trips(theta_v, phi_v, theta_l, phi_l):
    config = _lab(arm={"max_tilt_deg": 180.0})  # the arm's reach alone decides
    view, light = (theta_v, phi_v), (theta_l, phi_l)
    pose = bonn.inverse(config, view, light)
    got_view, got_light = bonn.forward(config, pose.rotation, pose.rail_deg)
    for got, want, residual in ((got_view, view, pose.view_residual_deg),
                                (got_light, light, pose.light_residual_deg)):  # fmt: skip
        err = angular_distance_deg(direction_vector(*got), direction_vector(*want))
        assert np.isfinite(err) and err == pytest.approx(residual, abs=1e-6)
    # only a pair closer than the rail's end leaves a residual, half the shortfall each
    gap = angular_distance_deg(direction_vector(*view), direction_vector(*light))
    shortfall = max(0.0, config.bonn.rail.axis.min_deg - gap)
    assert pose.view_residual_deg == pytest.approx(shortfall / 2, abs=1e-6)


def test_the_residual_table_of_a_sampling_on_the_bonn_lab():
    from rig.geometry import Sampling
    from rig.kinematics import sampling_residuals

    rows = sampling_residuals(_lab(), Sampling.named("H1"))
    assert rows[0]["theta_deg"] == 0 and rows[0]["max_view_residual_deg"] == pytest.approx(5.0)
    assert all(r["max_view_residual_deg"] < 1e-6 for r in rows[1:])


@scaled(2 / 3)
@given(
    st.floats(0, 85), st.floats(0, 360), st.floats(0, 85), st.floats(0, 360),
)  # fmt: skip
def test_a_recorded_step_places_the_lamp_and_bounds_its_displacement(
    theta_v, phi_v, theta_l, phi_l
):
    config = _lab(arm={"max_tilt_deg": 180.0})
    pose = bonn.inverse(config, (theta_v, phi_v), (theta_l, phi_l))
    actuators = recorded_actuators(pose.rotation, pose.rail_deg)
    lamp = bonn.recorded_lamp_mm(config, "lamp0", actuators)
    _, light = bonn.forward(config, pose.rotation, pose.rail_deg)
    assert np.linalg.norm(lamp) == pytest.approx(config.bonn.lamp_distance_mm)
    _close(direction_angles(lamp), light)
    bound = bonn.displaced_by_deg(config, actuators)
    assert max(pose.view_residual_deg, pose.light_residual_deg) <= bound + 1e-9
    assert bound in (0.0, 5.0)  # the rail's ends: 10° and 170°
    if bound == 0.0:
        assert pose.view_residual_deg < 1e-6 and pose.light_residual_deg < 1e-6
    with pytest.raises(KinematicsError, match="one lamp, 'lamp0'"):
        bonn.recorded_lamp_mm(config, "lamp1", actuators)
