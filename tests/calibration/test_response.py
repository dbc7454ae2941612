import numpy as np
import pytest
from numpy.testing import assert_allclose

from calibration.response import ResponseError, calibrate_response, merge_bracket

TIMES = np.array([1 / 64, 1 / 16, 1 / 4, 1.0, 4.0])


GAIN = 1.1  # the sensor clips at 1/1.1 of the curve's asymptote


def _true_inverse(values):
    y = np.asarray(values) / 255.0 / GAIN
    return y**1.8 / (1.0 - y**1.8)


def _camera(exposure):
    # A saturating, gamma-like response that clips: value = 255·1.1·(x/(1+x))^(1/1.8).
    value = 255 * GAIN * (exposure / (1 + exposure)) ** (1 / 1.8)
    return np.clip(np.round(value), 0, 255).astype(np.uint8)


@pytest.fixture(scope="module")
def bracket():
    rng = np.random.default_rng(0)
    radiance = np.exp(rng.uniform(np.log(0.05), np.log(20), (64, 96, 3)))
    return radiance, [_camera(radiance * t) for t in TIMES]


def test_recovers_the_response_curve(bracket):
    _, images = bracket
    curve = calibrate_response(images, TIMES).curve
    truth = _true_inverse(np.arange(256))
    truth = truth / truth[128]
    err = np.abs(curve[10:246] / truth[10:246, None] - 1)
    # 1 % where 8-bit quantisation allows it (20..235), 3 % down to 10 and up to 245.
    assert err[10:226].max() < 0.01
    assert err.max() < 0.03


def test_merged_radiance_is_linear_and_flags_clipping(bracket):
    radiance, images = bracket
    resp = calibrate_response(images, TIMES)
    merged = merge_bracket(images, TIMES, resp)
    assert merged.valid.all()
    scale = np.median(merged.radiance / radiance)
    assert_allclose(merged.radiance / scale, radiance, rtol=0.03)
    # Only the two longest exposures: the brightest pixels clip in both.
    clipped = merge_bracket(images[3:], TIMES[3:], resp)
    assert clipped.saturated.any()
    assert not clipped.valid[clipped.saturated].any()
    assert np.all(np.isfinite(clipped.radiance))
    assert np.all(clipped.radiance[~clipped.valid] == 0)


def test_one_exposure_is_a_clear_error(bracket):
    _, images = bracket
    with pytest.raises(ResponseError, match="at least 2 exposures"):
        calibrate_response(images[:1], TIMES[:1])
    with pytest.raises(ResponseError, match="distinct"):
        calibrate_response(images[:2], [1.0, 1.0])
    with pytest.raises(ResponseError, match="uint8"):
        calibrate_response([im.astype(np.float32) for im in images], TIMES)


def test_bad_sampling_options_are_named(bracket):
    _, images = bracket
    with pytest.raises(
        ResponseError, match=r"per_level = 0, smoothness = 100.0: need per_level ≥ 1"
    ):
        calibrate_response(images, TIMES, per_level=0)
    with pytest.raises(ResponseError, match="smoothness > 0"):
        calibrate_response(images, TIMES, smoothness=0.0)
