"""The area resampling filter: each pixel weighted by its share of the texel's footprint."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from processing.registration import Reason, RegistrationError, rectify
from processing.registration._homography import PlaneHomography

#: Pixels per texel side of the synthetic frames: not a whole number, so texel
#: edges cut pixels.
PX_PER_TEXEL = 2.5
TEXELS = 8


def _homography(px_per_mm: float, offset_px: float) -> PlaneHomography:
    """Plane (x, y) mm → pixels, x right and y down, the sample's corner at
    ``offset_px``: an axis-aligned scale, so the exact area weights are known."""
    half = TEXELS / 2  # sample_mm = TEXELS: one texel per mm
    H = np.array([[px_per_mm, 0.0, offset_px + half * px_per_mm],
                  [0.0, -px_per_mm, offset_px + half * px_per_mm],
                  [0.0, 0.0, 1.0]])  # fmt: skip
    empty = np.zeros(0, np.int64)
    return PlaneHomography(H, np.linalg.inv(H), True, Reason.OK, empty, np.zeros(0), 0.0, 0.0,
                           empty)  # fmt: skip


def _exact(frame: np.ndarray, offset_px: float) -> np.ndarray:
    """Each texel the mean of the frame's constant pixel squares over its footprint."""
    # pixel p spans [p − ½, p + ½] about its centre: [p, p + 1] in edge coordinates
    edges = offset_px + 0.5 + PX_PER_TEXEL * np.arange(TEXELS + 1)
    cells = np.arange(frame.shape[0] + 1)
    # overlap[t, p]: length of pixel p's [p, p+1) inside texel t's [e_t, e_t+1)
    lo = np.maximum(edges[:-1, None], cells[None, :-1])
    hi = np.minimum(edges[1:, None], cells[None, 1:])
    w = np.clip(hi - lo, 0.0, None) / PX_PER_TEXEL
    return np.einsum("ty,sx,yx->ts", w, w, frame[:, :, 0])


@pytest.fixture
def frame():
    rng = np.random.default_rng(3)
    return rng.uniform(0.0, 255.0, (32, 32, 1))


def test_the_area_filter_gives_the_exact_overlap_average(frame):
    H = _homography(PX_PER_TEXEL, 4.0)
    area = rectify(frame, H, sample_mm=TEXELS, size=TEXELS, filter="area").texture[..., 0]
    box = rectify(frame, H, sample_mm=TEXELS, size=TEXELS).texture[..., 0]
    exact = _exact(frame, 4.0)
    area_error = np.abs(area - exact).max() / 255.0
    # the footprint sampled at 4 points per pixel: its edges cut pixels at halves,
    # which the samples hit exactly
    assert area_error < 1e-5
    assert np.abs(box - exact).max() / 255.0 > 50 * max(area_error, 1e-6)


def test_nothing_outside_the_footprint_leaks_in():
    frame = np.full((32, 32, 1), 1000.0)
    # texel (2, 3) covers x 12.5…15, y 10…12.5 in pixel-edge coordinates: paint it 10
    frame[10:13, 12:15] = 10.0
    H = _homography(PX_PER_TEXEL, 4.5)
    texture = rectify(frame, H, sample_mm=TEXELS, size=TEXELS, filter="area").texture[..., 0]
    exact = _exact(frame, 4.5)
    np.testing.assert_allclose(texture, exact, rtol=1e-6)


def test_doubling_the_area_samples_changes_a_turned_footprint_little(frame, monkeypatch):
    """A rotated, sheared footprint: the weights converge as the sampling densifies."""
    import processing.registration._rectify as rect

    H = _homography(PX_PER_TEXEL, 4.0)
    turn = np.array([[np.cos(0.3), -np.sin(0.3) * 0.8, 0.0],
                     [np.sin(0.3), np.cos(0.3), 0.0], [0.0, 0.0, 1.0]])  # fmt: skip
    turned = dataclasses.replace(
        H,
        plane_to_image=H.plane_to_image @ turn,
        image_to_plane=np.linalg.inv(H.plane_to_image @ turn),
    )
    at = {}
    for density in (4, 8):
        monkeypatch.setattr(rect, "AREA_SAMPLES_PER_PIXEL", density)
        at[density] = rectify(frame, turned, sample_mm=6, size=6, filter="area").texture
    assert np.abs(at[4] - at[8]).max() / 255.0 < 0.02


def test_an_unknown_filter_names_the_valid_ones(frame):
    with pytest.raises(RegistrationError, match="filter = 'gauss': valid are \\['box', 'area'\\]"):
        rectify(frame, _homography(PX_PER_TEXEL, 4.0), sample_mm=TEXELS, size=TEXELS,
                filter="gauss")  # fmt: skip
