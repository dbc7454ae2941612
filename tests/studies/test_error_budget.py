"""The error budget's switches: each term off is a scene change, and only that."""

import numpy as np
import pytest

from processing.offline import BtfStage
from rig.errors import RigError
from sim.model import SceneModel
from sim.scene import scene_from_dict
from sim.world import WorldSnapshot
from studies.error_budget import (
    CONFIGS,
    PROCESSINGS,
    REGISTRATION_TERMS,
    TERMS,
    components_of,
    plot,
    run,
    scene_without,
)


def _lights(off):
    scene = scene_from_dict(scene_without("bumps", off))
    snap = WorldSnapshot(0.0, 30.0, 45.0, frozenset({"lamp3"}), False, 0.0, 0)
    return scene, SceneModel(scene).lights(snap)["lamp3"]


def test_every_term_is_off_alone_once_and_all_together():
    assert CONFIGS[0] == () and CONFIGS[-1] == tuple(TERMS)
    assert sorted(c[0] for c in CONFIGS[1:-1]) == sorted(TERMS)


def test_noise_off_drops_the_effect_and_nothing_else():
    on, off = (scene_from_dict(scene_without("weave", o)) for o in ((), ("noise",)))
    assert on.has("noise") and not off.has("noise")
    assert set(on.spec.effects) - set(off.spec.effects) == {"noise"}
    assert off.rig == on.rig


def test_lamps_at_infinity_give_the_centre_the_near_lamps_irradiance():
    _, near = _lights(())
    _, far = _lights(("near lamps",))
    assert (near.kind, far.kind) == ("point", "directional")
    points = np.array([[0.0, 0.0, 0.0], [45.0, -45.0, 0.0]])
    near_dirs, near_e = near.incident(points)
    far_dirs, far_e = far.incident(points)
    np.testing.assert_allclose(far_e, near_e[0], rtol=1e-12)  # the centre's, everywhere
    np.testing.assert_allclose(far_dirs[0], near_dirs[0], atol=1e-12)
    assert not np.isclose(near_e[1], near_e[0], rtol=0.05)  # near: 1/r² varies across


def test_pixels_integrate_their_area_when_point_pixels_are_off():
    assert scene_from_dict(scene_without("bumps", ())).spec.render.supersample == 1
    assert scene_from_dict(scene_without("bumps", ("point pixels",))).spec.render.supersample > 1


def test_the_frames_render_at_the_scale_asked_and_the_terms_stay_off():
    """The half-resolution sensor is held fixed by default; the camera's own resolution
    (or any other) is asked for, with every term still switched off as named."""
    assert scene_from_dict(scene_without("weave", ())).spec.render.scale == 0.5
    full = scene_from_dict(scene_without("weave", ("point pixels",), render_scale=1.0))
    assert (full.spec.render.scale, full.spec.render.supersample) == (1.0, 3)
    half = scene_from_dict(scene_without("weave", ("point pixels",)))
    assert full.rig.camera_arc.cameras[0].fx_px == 2 * half.rig.camera_arc.cameras[0].fx_px


@pytest.mark.parametrize(
    ("options", "message"),
    [({"render_scale": 0.0}, "render_scale=0.0: valid is 0 < scale ≤ 4"),
     ({"truth_rays": 4}, "truth_rays=4: valid is ≥ 8")],
)  # fmt: skip
def test_a_bad_scale_or_truth_says_what_is_valid(options, message):
    with pytest.raises(RigError, match=message):
        run(**options)


def test_an_unknown_term_names_the_valid_ones():
    with pytest.raises(RigError, match="unknown error terms \\['lens'\\]; valid terms"):
        scene_without("bumps", ("lens",))


def test_an_unknown_processing_names_the_valid_ones():
    with pytest.raises(RigError, match=r"\['sharpened'\]; .* processings \['raw', "):
        run(processings=("sharpened",))
    for options in PROCESSINGS.values():  # each a btf stage the options make valid
        BtfStage(size=8, **options)


def test_the_waterfall_is_drawn(tmp_path):
    rows = [{"scene": s, "plan": "coarse", "run": run, "processing": p, "components": c,
             "psnr_captured_db": 30.0 + k, "psnr_held_out_db": 22.0 + k}
            for s in ("bumps", "weave") for k, run in enumerate(("all terms on", "all terms off"))
            for p in ("raw", "irradiance per texel", "lights per texel")
            for c in (4, "lossless")]  # fmt: skip
    plot(rows, tmp_path / "budget.png")
    assert (tmp_path / "budget.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def _view_spread_deg(off) -> float:
    """The largest angle between the view rays to the sample's corners and centre."""
    scene = scene_from_dict(scene_without("bumps", off))
    camera = SceneModel(scene).camera("cam3")
    half = scene.rig.holder.sample_mm / 2
    points = np.array([[0, 0, 0], [half, half, 0], [-half, -half, 0], [half, -half, 0]], float)
    rays = camera.center - points
    rays /= np.linalg.norm(rays, axis=1, keepdims=True)
    return float(np.degrees(np.arccos(np.clip(rays[1:] @ rays[0], -1, 1))).max())


def test_perspective_off_sees_the_sample_along_nearly_parallel_rays():
    assert _view_spread_deg(()) > 4.0
    assert _view_spread_deg(("perspective",)) < 0.1
    near, far = (scene_from_dict(scene_without("bumps", o)).rig.camera_model("cam3")
                 for o in ((), ("perspective",)))  # fmt: skip
    # the same pixels on the sample: the sample's centre and corner land where they did
    corner = np.array([[0.0, 0.0, 0.0], [50.0, 50.0, 0.0]])
    np.testing.assert_allclose(far.project(corner)[0][0], near.project(corner)[0][0], atol=1e-6)
    assert np.abs(far.project(corner)[0][1] - near.project(corner)[0][1]).max() < 6.0  # px


def test_registration_terms_leave_the_scene_as_it_is():
    for term in REGISTRATION_TERMS:
        assert term in TERMS
        assert scene_without("weave", (term,)) == scene_without("weave", ())


@pytest.mark.slow  # two simulated frames
def test_the_telecentric_camera_renders_the_sample_as_the_near_one():
    from sim.simulator import Simulator

    frames = []
    for off in ((), ("perspective",)):
        with Simulator(scene_from_dict(scene_without("bumps", off))) as sim:
            frames.append(sim.render_state("cam3", lamps_on=["lamp3"]).image.astype(float))
    # the sample's middle, which both see on the same pixels (its edges move by a few)
    h, w = frames[0].shape[:2]
    near, far = (f[h // 2 - 40 : h // 2 + 40, w // 2 - 40 : w // 2 + 40] for f in frames)
    assert near.mean() > 10  # lit
    assert abs(far.mean() / near.mean() - 1) < 0.05  # not clipped away by the depth range


def test_lossless_is_every_component_not_the_colour_channels():
    from processing.btf import CompressedBTF

    views, c, n = 2, 5, 4
    btf = CompressedBTF(
        np.array([[0.0, 0.0], [45.0, 0.0]]), np.array([[30.0, 0.0]] * 7),
        np.zeros((views, n, n, 3), np.float16), np.zeros((views, c, n, n, 3), np.float16),
        np.zeros((views, 7, c), np.float32), np.zeros((views, 7), np.float32),
        np.full(views, c, np.int32),
    )  # fmt: skip
    assert components_of(btf) == c
