"""Sub-pixel peak detectors: known offsets of sampled Gaussians, degenerate windows."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from processing.mdf import PEAK_METHODS, MdfError, peak_offset, peak_radius


def gaussian_window(true_offset, sigma=1.0, radius=3):
    x = np.arange(-radius, radius + 1)[:, None] - np.asarray(true_offset)[None, :]
    return np.exp(-(x**2) / (2 * sigma**2))


OFFSETS = np.linspace(-0.49, 0.49, 41)


def test_gaussian_fit_is_exact_on_gaussians():
    off, ok = peak_offset(gaussian_window(OFFSETS, sigma=1.3), method="gaussian")
    assert ok.all()
    np.testing.assert_allclose(off, OFFSETS, atol=1e-12)


@pytest.mark.parametrize(("method", "tol"), [("centroid", 0.05), ("blais_rioux", 0.03)])
def test_other_detectors_are_close_on_gaussians(method, tol):
    off, ok = peak_offset(gaussian_window(OFFSETS, sigma=1.0), method=method)
    assert ok.all()
    np.testing.assert_allclose(off, OFFSETS, atol=tol)
    # Monotone in the true offset: a detector that ignored the data would fail.
    assert np.all(np.diff(off) > 0)


@pytest.mark.parametrize("method", PEAK_METHODS)
def test_flat_window_is_flagged(method):
    off, ok = peak_offset(np.ones((7, 4)), method=method)
    assert not ok.any()
    assert np.all(off == 0)


def test_needs_enough_samples_and_known_method():
    with pytest.raises(MdfError, match="needs an odd count"):
        peak_offset(np.ones((3, 2)), method="blais_rioux")
    with pytest.raises(MdfError, match="valid are"):
        peak_radius("parabola")
    assert [peak_radius(m) for m in ("gaussian", "centroid", "blais_rioux")] == [1, 2, 3]


@given(
    arrays(np.float64, (7, 5), elements=st.floats(0, 1e4, allow_nan=False)),
    st.sampled_from(PEAK_METHODS),
)
def test_any_window_gives_finite_bounded_offsets(window, method):
    off, ok = peak_offset(window, method=method)
    assert off.shape == ok.shape == (5,)
    assert np.all(np.isfinite(off))
    assert np.all(np.abs(off) <= 1)
    assert np.all(off[~ok] == 0)
