import itertools

import pytest
from numpy.testing import assert_allclose
from pydantic import ValidationError

from rig.config import default_rig_config
from rig.errors import PlanError
from rig.plan import parse_plan
from rig.schedule import compile_plan

CONFIG = default_rig_config()

PLAN = """
[sample]
name = "s"
[captures.btf]
views = "H2"
lights = [[30, 0], [45, 90], [60, 200]]
[captures.ps]
lights = {theta_deg = 45, count = 6}
[captures.mdf]
views = [[0, 0], [45, 90]]
laser_locations = {theta_deg = 45, count = 4}
scan_step_deg = 0.5
[exposure]
exposure_s = 0.01
hdr_brackets = [1, 4]
"""


@pytest.fixture(scope="module")
def schedule():
    return compile_plan(parse_plan(PLAN), CONFIG)


def test_every_pair_captured_exactly_once(schedule):
    seen = [(s.kind, sh.view_deg, sh.light_deg) for s in schedule.steps for sh in s.shots]
    assert len(seen) == len(set(seen)) == schedule.pairs == 81 * 3 + 6 + 2 * 4


def test_steps_group_cameras_and_keep_positions_together(schedule):
    positions = [tuple(s.pose) for s in schedule.steps]
    # A position, once left, is never returned to.
    left = set()
    for prev, cur in itertools.pairwise(positions):
        if cur != prev:
            left.add(prev)
            assert cur not in left
    assert max(len(s.shots) for s in schedule.steps) > 1  # cameras fire together
    assert [s.index for s in schedule.steps] == list(range(len(schedule.steps)))


def test_ordering_saves_motion_and_estimate_adds_up(schedule):
    est, naive = schedule.estimate, schedule.naive_estimate
    assert est.motion_s < naive.motion_s
    assert_allclose(est.capture_s, naive.capture_s)  # same work, other order
    assert_allclose(est.total_s, est.motion_s + est.lamp_s + est.capture_s)
    assert_allclose(sum(est.by_kind_s.values()), est.total_s)


def test_data_size_counts_every_frame(schedule):
    frame = 1024 * 768 * 3
    lamp_frames = sum(len(s.shots) * 2 for s in schedule.steps if s.kind != "mdf")
    scan = [s for s in schedule.steps if s.kind == "mdf"]
    assert scan[0].scan_frames == 12 / 0.5 + 1
    mdf_frames = sum(len(s.shots) * s.scan_frames for s in scan)
    assert schedule.estimate.frames == lamp_frames + mdf_frames
    assert schedule.estimate.bytes == frame * (lamp_frames + mdf_frames)


def test_laser_exposure_longer_than_frame_period_is_rejected():
    plan = parse_plan(
        PLAN.replace("exposure_s = 0.01", "exposure_s = 0.01\nlaser_exposure_s = 0.5")
    )
    with pytest.raises(PlanError, match="laser_exposure_s"):
        compile_plan(plan, CONFIG)


def test_unreachable_directions_report_residuals():
    plan = parse_plan('[sample]\nname="s"\n[captures.btf]\nviews="H1"\nlights="H1"')
    s = compile_plan(plan, CONFIG)
    assert_allclose(s.max_view_residual_deg, 10.0, atol=1e-6)  # 85° ring → 75° camera


def test_fixed_shots_go_where_they_say_and_bad_ids_are_named():
    config = default_rig_config()
    plan = parse_plan(
        '[sample]\nname = "fixed"\n'
        '[[captures.fixed]]\nturntable_deg = 30.0\nlamp = "lamp2"\ncameras = ["cam0", "cam3"]\n'
        '[[captures.fixed]]\nturntable_deg = 200.0\narc_deg = 45.0\nlamp = "lamp0"\n'
    )
    steps = compile_plan(plan, config).steps
    where = {(*s.pose, s.source): s.cameras for s in steps}
    assert where[(30.0, 0.0, "lamp2")] == ("cam0", "cam3")
    assert len(where[(200.0, 45.0, "lamp0")]) == len(config.camera_arc.cameras)
    bad = parse_plan(
        '[sample]\nname = "fixed"\n'
        '[[captures.fixed]]\nturntable_deg = 0.0\nlamp = "lamp99"\ncameras = ["cam9"]\n'
    )
    with pytest.raises(PlanError) as info:
        compile_plan(bad, config)
    assert "captures.fixed[0].lamp" in str(info.value)
    assert "captures.fixed[0].cameras" in str(info.value)


def test_laser_locations_go_to_the_mount_of_their_elevation():
    laser = CONFIG.laser.model_copy(update={"mount_theta_deg": (45.0, -20.0)})
    config = CONFIG.model_copy(update={"laser": laser})
    plan = parse_plan(
        '[sample]\nname = "m"\n[captures.mdf]\nviews = [[0, 0]]\n'
        "laser_locations = [[45, 0], [20, 90], [20, 270]]\n"
    )
    steps = compile_plan(plan, config).steps
    by_location = {s.shots[0].light_deg: s.source for s in steps}
    assert by_location == {(45.0, 0.0): "laser0", (20.0, 90.0): "laser1", (20.0, 270.0): "laser1"}
    assert max(s.shots[0].light_residual_deg for s in steps) < 1e-6
    with pytest.raises(ValidationError, match=r"mount_theta_deg \[45.0, 20.0, 10.0\]: .* 1 or 2"):
        CONFIG.laser.model_validate(
            {**CONFIG.laser.model_dump(), "mount_theta_deg": (45.0, 20.0, 10.0)}
        )
