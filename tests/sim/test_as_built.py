"""The scene's ``[as_built]`` table: a simulated rig that stands off its config."""

import numpy as np
import pytest
from numpy.testing import assert_allclose

from rig.errors import ConfigError
from rig.kinematics import lamp_position_mm, rotate_z
from sim.model import SceneModel
from sim.scene import scene_from_dict
from sim.world import WorldSnapshot

BASE = {"sample": {"generator": "flat"}, "render": {"scale": 0.25}}
TABLE = {"seed": 3, "lamp_position_mm": 5.0, "lamp_intensity": 0.1,
         "camera_position_mm": 2.0, "camera_rotation_deg": 0.5}  # fmt: skip


def _scene(as_built: dict | None = None):
    return scene_from_dict(BASE | ({"as_built": as_built} if as_built is not None else {}))


@pytest.mark.parametrize(
    ("table", "says"),
    [
        ({"lamp_intensity": 1.0}, "as_built.lamp_intensity: Input should be less than 1"),
        ({"lamp_position_mm": -2.0}, "as_built.lamp_position_mm: Input should be greater than or"),
        ({"camera_rotation_deg": 20.0}, "as_built.camera_rotation_deg: Input should be less"),
        ({"seed": -1}, "as_built.seed: Input should be greater than or equal to 0"),
        ({"lamp_offset": 1.0}, "as_built.lamp_offset: unknown field; valid fields here are"),
    ],
)  # fmt: skip
def test_a_bad_as_built_value_is_refused_naming_the_field_and_what_is_valid(table, says):
    with pytest.raises(ConfigError, match=says):
        _scene(table)


def test_a_rig_built_to_its_config_has_no_deviations():
    assert _scene().as_built is None
    assert _scene({"seed": 5}).as_built is None  # amounts 0: exact, whatever the seed


def test_the_deviations_stay_within_their_bounds_and_repeat_with_the_seed():
    built = _scene(TABLE).as_built
    offsets = np.stack(list(built.lamp_offset_mm.values()))
    gains = np.array(list(built.lamp_gain.values()))
    assert sorted(built.lamp_offset_mm) == [f"lamp{i}" for i in range(8)]
    assert np.abs(offsets).max() <= 5.0 and np.abs(offsets).max() > 2.5
    assert np.abs(gains - 1).max() <= 0.1 and np.abs(gains - 1).max() > 0.05
    again = _scene(TABLE).as_built
    assert_allclose(np.stack(list(again.lamp_offset_mm.values())), offsets)
    other = _scene(TABLE | {"seed": 4}).as_built
    assert not np.allclose(np.stack(list(other.lamp_offset_mm.values())), offsets)


def test_each_amount_draws_from_its_own_stream():
    built = _scene(TABLE).as_built
    brighter = _scene(TABLE | {"lamp_intensity": 0.2}).as_built
    for lamp, offset in built.lamp_offset_mm.items():
        assert_allclose(brighter.lamp_offset_mm[lamp], offset)
        assert brighter.lamp_gain[lamp] - 1 == pytest.approx(2 * (built.lamp_gain[lamp] - 1))


def test_the_simulator_places_and_powers_the_lamps_as_built_and_the_config_stays_nominal():
    scene, exact = _scene(TABLE), _scene()
    assert scene.rig == exact.rig  # what the daemon is told
    snapshot = WorldSnapshot(t=0.0, turntable_deg=30.0, arc_deg=50.0, lamps_on=frozenset({"lamp3"}),
                             laser_on=False, laser_tilt_deg=0.0, laser_mount=0)  # fmt: skip
    light = SceneModel(scene).lights(snapshot)["lamp3"]
    nominal = SceneModel(exact).lights(snapshot)["lamp3"]
    assert_allclose(nominal.position, lamp_position_mm(scene.rig, "lamp3", arc_deg=50.0,
                                                       turntable_deg=30.0))  # fmt: skip
    # the offset is in the arc's frame at 0°: it turns with the arc, against the turntable
    offset = rotate_z(scene.as_built.lamp_offset_mm["lamp3"], 50.0 - 30.0)
    assert_allclose(light.position, nominal.position + offset)
    assert light.intensity_w_sr == pytest.approx(
        nominal.intensity_w_sr * scene.as_built.lamp_gain["lamp3"]
    )


def test_a_camera_as_built_moves_on_its_mount():
    scene, exact = _scene(TABLE), _scene()
    camera, nominal = SceneModel(scene).camera("cam2"), SceneModel(exact).camera("cam2")
    turn = camera.R @ nominal.R.T
    angle = np.degrees(np.arccos(np.clip((np.trace(turn) - 1) / 2, -1, 1)))
    assert 0.0 < angle <= 0.5 * np.sqrt(3)
    shift = np.linalg.norm(camera.center - nominal.center)
    assert 0.0 < shift <= 2.0 * np.sqrt(3)  # the turn is about the centre: it does not move it
    assert_allclose(camera.K, nominal.K)
