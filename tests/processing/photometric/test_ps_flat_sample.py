"""A flat sample integrates flat: ``flat_beyond_mm`` against the simulator's weave and
against surfaces with a known spectrum (docs/photometric.md, "A flat sample")."""

from __future__ import annotations

import numpy as np
import pytest

from processing.photometric import PhotometricError, integrate_gradients, integrate_normals
from sim.scene import load_scene
from tests.processing.photometric.flat_truth import low_frequency_std, texel_truth_over_footprints

N = 128


@pytest.fixture(scope="module")
def weave():
    return texel_truth_over_footprints(load_scene("examples/scenes/default.toml"), N)


def test_the_weave_integrates_to_its_truth_with_no_shape_of_its_own(weave):
    normals, truth, pitch = weave
    # the texel-sampled normals cannot show the yarns' sides and the floor between them:
    # integrated as they are, they make a bowl at the weave's beat with the grid
    raw = integrate_normals(normals, pitch_mm=pitch).height_mm
    assert low_frequency_std(raw - truth) > 0.3  # measured 0.358; the truth's own: 0.003
    flat = integrate_normals(normals, pitch_mm=pitch, flat_beyond_mm=15.0).height_mm
    assert low_frequency_std(flat - truth) < 0.01  # measured 0.0067
    assert low_frequency_std(flat) < 0.01  # measured 0.0061, the truth's 0.0032


def _cosine_slopes(width: int, half_periods: tuple[int, ...], pitch_mm: float):
    """(width, width) exact ∂h/∂x of a sum of DCT-II cosines along the columns, 0.1 mm high,
    each ``k`` half-periods across the width (wavelength 2 · width · pitch / k)."""
    x = (np.arange(width) + 0.5) / width * np.pi
    slope = sum(-0.1 * k * np.pi / (width * pitch_mm) * np.sin(k * x) for k in half_periods)
    return np.tile(slope, (width, 1))


def _amplitude(height, k: int) -> float:
    x = (np.arange(height.shape[1]) + 0.5) / height.shape[1] * np.pi
    return float(2.0 * np.mean(height * np.cos(k * x)[None, :]))


@pytest.mark.parametrize("method", ["dct", "lsq"])
def test_wavelengths_below_half_the_cutoff_stay_and_above_twice_it_go(method):
    width, pitch = 128, 0.5  # 64 mm: k half-periods are 128 / k mm long
    p = _cosine_slopes(width, (4, 16), pitch)  # 32 mm and 8 mm
    mask = np.ones((width, width), bool)
    mask[60:64, 30:34] = method == "dct"  # lsq: a hole, which the plane fit skips
    got = integrate_gradients(p, np.zeros_like(p), pitch_mm=pitch, mask=mask, method=method,
                              flat_beyond_mm=16.0).height_mm  # fmt: skip
    got = np.where(mask, got, 0.0)
    # 1 / (1 + (λ / 16 mm)^8): 0.996 at 8 mm, 0.004 at 32 mm; the integrators' finite
    # differences of averaged slopes give a cosine of ω rad per pixel (ω/2) / tan(ω/2) of it
    half = np.pi / 16  # ω / 2 at 16 pixels a period
    assert _amplitude(got, 16) == pytest.approx(0.1 * 0.996 * half / np.tan(half), rel=2e-3)
    assert abs(_amplitude(got, 4)) < 0.1 * 0.01


def test_a_tilted_plane_is_flat_and_bad_cutoffs_are_named():
    p = np.full((32, 32), 0.2)
    flat = integrate_gradients(p, -0.1 * np.ones_like(p), pitch_mm=0.5, flat_beyond_mm=10.0)
    assert np.abs(flat.height_mm).max() < 1e-9
    for bad in (0.0, -1.0, np.inf, np.nan):
        with pytest.raises(PhotometricError, match="flat_beyond_mm"):
            integrate_gradients(p, p, pitch_mm=0.5, flat_beyond_mm=bad)
