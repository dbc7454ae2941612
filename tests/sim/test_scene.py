"""Scene validation: every problem names its field, value and what is valid."""

from pathlib import Path

import pytest

from rig.errors import ConfigError
from rig.plan import load_plan
from sim import load_scene, scene_from_dict

SCENES = sorted((Path(__file__).parents[2] / "examples" / "scenes").glob("*.toml"))


def _problems(data) -> str:
    with pytest.raises(ConfigError) as info:
        scene_from_dict(data)
    return str(info.value)


def test_unknown_field_lists_valid_fields():
    msg = _problems({"sample": {"generator": "bumps", "colour": 1}})
    assert "sample.colour: unknown field" in msg
    assert "depth_mm" in msg


def test_bad_effect_and_params_for_unlisted_effect():
    msg = _problems({"sample": {"generator": "bumps"}, "effects": ["glow"]})
    assert "effects.0" in msg and "glow" in msg and "shadows" in msg
    msg = _problems({"sample": {"generator": "bumps"}, "noise": {"read_noise_e": 3}})
    assert "noise: parameters given but 'noise' is not in effects" in msg


def test_generator_params_are_validated_with_their_path():
    msg = _problems({"sample": {"generator": "bumps", "params": {"amplitude_mm": -1}}})
    assert "sample.params.amplitude_mm" in msg and "-1" in msg
    msg = _problems({"sample": {"generator": "spiral"}})
    assert "sample.generator" in msg and "weave" in msg


def test_several_problems_reported_at_once():
    msg = _problems(
        {
            "sample": {"generator": "weave", "params": {"pitch_mm": 0}, "materials": ["silk"]},
            "rig": {"overrides": {"holder": {"sample_mm": -5}}},
        }
    )
    assert "sample.params.pitch_mm" in msg
    assert "silk" in msg
    assert "rig.holder.sample_mm" in msg


def test_lens_distortion_must_match_the_cameras():
    cams = [{"id": "c", "theta_deg": 0, "dist": [0.1, 0, 0, 0, 0]}]
    rig = {"overrides": {"camera_arc": {"cameras": cams}}}
    msg = _problems({"sample": {"generator": "flat"}, "rig": rig})
    assert "'lens_distortion' is not in effects" in msg
    msg = _problems(
        {
            "sample": {"generator": "flat"},
            "rig": rig,
            "effects": ["lens_distortion"],
            "lens_distortion": {"coefficients": [0.2, 0, 0, 0, 0]},
        }
    )
    assert "lens_distortion.coefficients" in msg
    scene = scene_from_dict(
        {
            "sample": {"generator": "flat"},
            "effects": ["lens_distortion"],
            "lens_distortion": {"coefficients": [-0.1, 0.01, 0, 0, 0]},
        }
    )
    assert all(c.dist == (-0.1, 0.01, 0, 0, 0) for c in scene.rig.camera_arc.cameras)


def test_scale_scales_intrinsics():
    scene = scene_from_dict({"sample": {"generator": "flat"}, "render": {"scale": 0.25}})
    cam = scene.rig.camera("cam0")
    assert (cam.width, cam.height, cam.fx_px) == (256, 192, 750.0)


def test_sample_must_fit_the_recess():
    msg = str(_build_error({"generator": "bumps", "depth_mm": 0.5,
                            "params": {"amplitude_mm": 1.0}}))  # fmt: skip
    assert "recess" in msg


def _build_error(sample):
    from sim.model import SceneModel

    model = SceneModel(scene_from_dict({"sample": sample}))
    with pytest.raises(ConfigError) as info:
        _ = model.sample
    return info.value


@pytest.mark.parametrize("path", SCENES, ids=[p.stem for p in SCENES])
def test_example_scenes_are_valid(path):
    assert load_scene(path).spec.sample.generator


def test_the_scene_or_the_caller_picks_the_rig_kind():
    from sim.scene import load_scene

    scene = load_scene("examples/scenes/virtex.toml")
    assert scene.rig.kind == "virtex" and len(scene.rig.lamps) == 6
    wang = load_scene("examples/scenes/bumps.toml")
    assert wang.rig.kind == "wang"
    stage = load_scene("examples/scenes/bumps.toml", kind="virtex")
    assert stage.rig.kind == "virtex" and [c.theta_deg for c in stage.rig.camera_arc.cameras] == [0]
    assert stage.rig.device_roles == ("lamp_bank",)


def test_the_demo_plan_describes_the_scene_it_runs_on():
    """`make demo` and the README run examples/plans/demo.toml on the default scene."""
    examples = Path(__file__).parents[2] / "examples"
    scene = load_scene(examples / "scenes" / "default.toml")
    description = load_plan(examples / "plans" / "demo.toml").sample.description
    assert scene.spec.sample.generator in description, (scene.spec.sample.generator, description)
