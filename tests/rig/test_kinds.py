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
        ("kind = 'tripod'", r"kind: Input should be 'wang', 'bonn' or 'virtex'"),
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
