"""Rig configs name their kind; each kind's section describes its geometry."""

import numpy as np
import pytest

from rig.config import RigConfig, load_rig_config, write_rig_config
from rig.errors import ConfigError


def test_a_virtex_ring_spaces_its_lamps_equally_at_one_elevation():
    config = RigConfig.model_validate(
        {"kind": "virtex", "virtex": {"lamp_count": 6, "lamp_theta_deg": 40, "phi0_deg": 10}}
    )
    stage = config.virtex
    assert [lamp.theta_deg for lamp in config.lamps] == [40.0] * 6
    azimuths = np.array([stage.azimuth_deg(i) for i in range(6)])
    np.testing.assert_allclose(np.diff(azimuths), 60.0)
    assert azimuths[0] == 10.0
    assert [c.theta_deg for c in config.camera_arc.cameras] == [0.0]
    assert config.device_roles == ("lamp_bank",)


def test_kind_configs_round_trip_through_toml(tmp_path):
    for data in ({"kind": "virtex", "virtex": {"lamp_count": 4}}, {"kind": "bonn", "bonn": {}}):
        config = RigConfig.model_validate(data)
        assert load_rig_config(write_rig_config(config, tmp_path / "rig.toml")) == config


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("kind = 'virtex'", r"kind 'virtex' needs its \[virtex\] section"),
        ("[virtex]\nlamp_count = 3", r"\[virtex\] describes a 'virtex' rig but kind is 'wang'"),
        ("kind = 'virtex'\n[virtex]\nlamp_count = 2", r"virtex.lamp_count: .*greater than or"),
        ("kind = 'tripod'", r"kind: unknown rig kind 'tripod'; valid are \['bonn', 'virtex'"),
        (
            "kind = 'virtex'\n[virtex]\n[[camera_arc.cameras]]\nid = 'c1'\ntheta_deg = 30",
            r"camera_arc.cameras \['c1'\]: a VirTex stage's camera looks straight down",
        ),
        (
            "kind = 'bonn'\n[bonn.rail.axis]\nspeed_deg_s = 5\naccel_deg_s2 = 5\nmin_deg = 0\n"
            "max_deg = 90",
            r"bonn.rail: .*must lie inside \(0, 180\)",
        ),
        (
            "kind = 'bonn'\n[bonn.rail.device]\nkind = 'canopen'",
            r"bonn.rail.device: kind 'canopen' is not known here; valid kinds are 'modbus'",
        ),
    ],
)
def test_bad_kind_configs_name_the_field_and_what_is_valid(tmp_path, text, message):
    path = tmp_path / "rig.toml"
    path.write_text(text)
    with pytest.raises(ConfigError, match=message):
        load_rig_config(path)


def test_a_wang_rig_has_no_rail():
    with pytest.raises(ConfigError, match=r"a 'wang' rig has no rail; its devices are"):
        RigConfig().device_section("rail")


def _virtex(count=3, **stage):
    return RigConfig.model_validate({"kind": "virtex", "virtex": {"lamp_count": count, **stage}})


def test_virtex_forward_and_inverse_meet_at_every_lamp():
    from rig.kinds import rig_kind
    from rig.steps import AxesPose, Shot, Step

    config = _virtex(6, phi0_deg=15.0, lamp_theta_deg=40.0, radius_mm=500.0)
    virtex = rig_kind(config)
    for i, lamp in enumerate(config.lamps):
        shot = Shot("cam0", (0.0, 0.0), (0.0, 0.0), 0.0, 0.0)
        step = Step(0, "ps", AxesPose(0.0, 0.0), lamp.id, (shot,), (0.01,))
        views, light = virtex.step_directions(config, step)
        np.testing.assert_allclose(views["cam0"][0], 0.0, atol=1e-9)
        np.testing.assert_allclose(light, [40.0, 15.0 + 60.0 * i], atol=1e-9)
        pose = virtex.inverse(config, (0.0, 0.0), (40.0, 15.0 + 60.0 * i + 5.0))
        assert pose.lamp == lamp.id and (pose.turntable_deg, pose.arc_deg) == (0.0, 0.0)
        np.testing.assert_allclose(pose.light_residual_deg, 5.0 * np.sin(np.deg2rad(40)), rtol=0.01)
        position = virtex.recorded_lamp_mm(config, lamp.id, {})
        np.testing.assert_allclose(np.linalg.norm(position), 500.0)


def test_a_virtex_plan_compiles_to_lamp_steps_without_motion():
    from rig.plan import parse_plan
    from rig.schedule import compile_plan

    plan = parse_plan('[sample]\nname = "s"\n[captures.ps]\nlights = {theta_deg = 45, count = 3}\n')
    schedule = compile_plan(plan, _virtex(3))
    assert [s.source for s in schedule.steps] == ["lamp0", "lamp1", "lamp2"]
    assert schedule.estimate.motion_s == 0.0 and schedule.estimate.frames == 3
    assert schedule.max_light_residual_deg < 1e-9


@pytest.mark.parametrize(
    ("captures", "message"),
    [
        ("[captures.btf]\nviews = 'H1'\nlights = 'H1'", r"captures.btf: a VirTex stage captures "
         r"photometric stereo only \(captures.ps\): its one camera looks straight down"),
        ("[captures.mdf]\nviews = [[0, 0]]\nlaser_locations = [[45, 0]]",
         r"captures.mdf: .* it has no laser unit"),
        ("[captures.ps]\nlights = {theta_deg = 30, count = 3}",
         r"captures.ps.lights: light \(30.0, 0.0\) is 15.0° from the nearest lamp \(lamp0\); "
         r"the stage's lamps are at theta_deg 45, phi_deg 0, 120, 240"),
        ("[captures.ps]\nviews = [[20, 0]]\nlights = {theta_deg = 45, count = 3}",
         r"captures.ps.views: view \(20.0, 0.0\) is 20.0° from the stage camera's view"),
    ],
)  # fmt: skip
def test_a_virtex_stage_refuses_what_it_cannot_capture(captures, message):
    from rig.errors import PlanError
    from rig.plan import parse_plan
    from rig.schedule import compile_plan

    plan = parse_plan(f'[sample]\nname = "s"\n{captures}\n')
    with pytest.raises(PlanError, match=message):
        compile_plan(plan, _virtex(3))


def test_every_registered_kind_answers_the_whole_interface():
    from rig.kinds import RigKind, kind_names, rig_kind

    assert {"wang", "bonn", "virtex"} <= set(kind_names())
    for name in kind_names():
        kind = rig_kind(name)
        assert isinstance(kind, RigKind) and kind.name == name
