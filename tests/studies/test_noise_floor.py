"""The noise floor, derived from the sensor model, against a loop whose only error is noise."""

import tempfile
from pathlib import Path

import numpy as np
import pytest

from processing.btf import psnr_db, rmse
from rig.config import RigConfig
from sim.scene import NoiseParams, scene_from_dict
from studies.noise_floor import floor_db, leverage, pixel_variance_dn, texel_noise_gain

# a flat, grey-brown Lambertian plate under lamps at infinity: its truth is one value per
# light, whatever the view, the pixel or the registration; a small full well makes the
# noise the only error by far (about 47 dB against the plate's systematic ≥ 60 dB)
_LAMPS = [lamp.model_dump() | {"kind": "directional"} for lamp in RigConfig().light_arc.lamps]
_FLAT = {
    "effects": ["noise"], "noise": {"full_well_e": 2000.0},
    "sample": {"generator": "flat", "depth_mm": 1.0, "materials": ["m"]},
    "materials": {"m": {"albedo": {"kind": "constant", "rgb": [0.7, 0.5, 0.3]}}},
    "render": {"scale": 0.5}, "rig": {"overrides": {"light_arc": {"lamps": _LAMPS}}},
}  # fmt: skip
_PLAN = (
    '[sample]\nname = "floor"\n[captures.btf]\nviews = [[0, 0], [45, 0]]\n'
    "lights = [[15, 0], [45, 90], [45, 270]]\n[exposure]\nexposure_s = 0.05\n"
)


def test_pixel_variance_is_shot_read_and_quantisation():
    noise = NoiseParams(full_well_e=1000.0, read_noise_e=10.0)
    gain = 255 / 1000.0  # DN per electron of an 8-bit sensor
    var = pixel_variance_dn(np.array([0.0, 100.0]), bit_depth=8, noise=noise)
    read = (10 * gain) ** 2
    np.testing.assert_allclose(var, [read + 1 / 12, 100 * gain + read + 1 / 12])
    np.testing.assert_allclose(pixel_variance_dn(np.array([50.0]), bit_depth=8, noise=None), 1 / 12)


def test_a_texel_of_many_pixels_averages_their_noise_and_the_tent_spreads_it():
    camera = RigConfig().camera_model("cam0")
    coarse, fine = (texel_noise_gain(camera, 100.0, n) for n in (64, 128))
    # 2 × fewer texels per side (3 and 6 pixels): about 4 × the pixels, 1/4 of the gain
    assert 3 < fine.mean() / coarse.mean() < 5
    # the bilinear tent spreads a texel past its footprint: more pixels than the area's
    area = texel_noise_gain(camera, 100.0, 64, filter="area")
    assert coarse.mean() < area.mean()


@pytest.mark.slow  # a six-frame session, processing and its truth: about 25 s
def test_a_loop_whose_only_error_is_noise_scores_its_floor():
    from sim.simulator import Simulator
    from studies.footprint import truth_at
    from studies.noise_floor import capture_gains
    from studies.render_loop import irradiance_scale, process, reconstructed, record, truncated

    scene, size = scene_from_dict(_FLAT), 32
    pairs = [(j, i) for j in range(2) for i in range(3)]
    with tempfile.TemporaryDirectory(prefix="rig-noise-floor-") as tmp:
        archive, config = record(scene, _PLAN, Path(tmp))
        btf = process(archive, size=size, components=3).btf  # lossless: three lights
        gains, exposures = capture_gains(archive, pairs, size=size)
    scale = irradiance_scale(scene, config)
    with Simulator(scene) as sim:
        truth = truth_at(sim, [(btf.view_dirs_deg[j], btf.light_dirs_deg[i]) for j, i in pairs],
                         size, 2)  # fmt: skip
    camera = config.camera_arc.cameras[0]
    sensor = {"scale": scale, "exposure_s": exposures, "bit_depth": camera.bit_depth,
              "noise": scene.spec.params("noise"), "peak": float(truth.max())}  # fmt: skip
    for c in (3, 1):  # lossless; one component holds the plate's whole signal, less noise
        model = truncated(btf, c)
        measured = psnr_db(rmse(reconstructed(model, pairs) / scale, truth), peak=sensor["peak"])
        kept = leverage(model, pairs, c)
        floor = floor_db(truth, gains, kept=kept, **sensor)
        assert abs(measured - floor) < 0.5, (c, measured, floor)
    assert kept.mean() < 0.9  # c = 1 of three lights keeps less than all the noise


def test_the_compressed_model_keeps_the_noise_its_components_span():
    from processing.btf import CompressedBTF

    lights, c, n = 4, 3, 2
    weights = np.zeros((1, lights, c), np.float32)
    weights[0, :, 0] = [5.0, -5.0, 0.0, 0.0]  # a centred component, scaled with its basis
    weights[0, :, 1] = [1.0, 1.0, -1.0, -1.0]
    weights[0, :, 2] = [0.0, 0.0, 2.0, -2.0]
    btf = CompressedBTF(
        np.array([[0.0, 0.0]]), np.array([[30.0, 90.0 * k] for k in range(lights)]),
        np.zeros((1, n, n, 3), np.float16), np.zeros((1, c, n, n, 3), np.float16), weights,
        np.array([[3.0, 2.0, 1.0, 0.0]], np.float32), np.array([c], np.int32),
    )  # fmt: skip
    pairs = [(0, light) for light in range(lights)]
    # the mean (1/4) and the first component's share of lights 0 and 1 (1/2 each)
    np.testing.assert_allclose(leverage(btf, pairs, 1), [0.75, 0.75, 0.25, 0.25])
    np.testing.assert_allclose(leverage(btf, pairs, 3), 1.0)  # mean + 3 of 4 − 1: lossless
