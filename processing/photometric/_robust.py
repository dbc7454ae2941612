"""Per-observation weights that reject shadows and highlights.

Two strategies, compared in ``docs/photometric.md``:

``threshold``
    Relative to the pixel's own values: rank the observations, drop the
    brightest ``highlight_fraction`` (specular spikes sit there) and every
    observation darker than ``shadow_fraction`` × the brightest one kept
    (attached and cast shadows).
``irls``
    Iteratively reweighted least squares with Tukey's biweight on the
    residuals of the Lambertian fit, starting from the ``threshold`` weights.
    The scale is the median absolute residual (MAD) of the observations in
    play, with a floor so noise-free data keeps unit weights.

Both return float32 weights in [0, 1] of shape (L, n) (weights need no more
digits; the sums of the fit take them into float64); saturated observations
always get 0.
"""

from __future__ import annotations

import numpy as np

from . import _system
from ._irls_kernel import irls_fit_kernel
from ._kernels import sum_arrays

#: Tukey biweight tuning constant (95 % efficiency under Gaussian noise).
TUKEY_C = 4.685
#: MAD → standard deviation for Gaussian noise.
_MAD_TO_SIGMA = 1.4826
#: Scale floor relative to the pixel's reference brightness.
_SCALE_FLOOR = 1e-3


def reference_level(grey: np.ndarray, highlight_fraction: float) -> np.ndarray:
    """The brightest observation kept after dropping the top ``highlight_fraction``: (n,)."""
    n_lights = grey.shape[0]
    k_drop = highlight_count(n_lights, highlight_fraction)
    rank = n_lights - 1 - k_drop
    # Partitioning contiguous rows, one per pixel, is ~4× faster than along axis 0.
    return np.partition(grey.T.copy(), rank, axis=1)[:, rank]


def highlight_count(n_lights: int, highlight_fraction: float) -> int:
    """How many of the brightest observations the threshold method drops (keeps ≥ 3)."""
    return max(0, min(int(highlight_fraction * n_lights), n_lights - 3))


def threshold_weights(
    grey: np.ndarray, usable: np.ndarray, *, shadow_fraction: float, highlight_fraction: float
) -> np.ndarray:
    """0/1 weights from thresholds relative to each pixel's own values."""
    ref = reference_level(grey, highlight_fraction)
    keep = usable & (grey >= shadow_fraction * ref) & (grey <= ref)
    return keep.astype(np.float32)


def irls_weights(
    grey: np.ndarray,
    usable: np.ndarray,
    lights: np.ndarray,
    *,
    shadow_fraction: float,
    highlight_fraction: float,
    iterations: int,
    max_condition: float,
) -> np.ndarray:
    """Tukey-biweight IRLS weights after ``iterations`` reweighting steps.

    Starts from :func:`threshold_weights`; every observation above the shadow
    floor may come back in (a bright but consistent lamp is not a highlight)
    or drop out (a cast shadow or a specular tail above the floor). The
    per-observation arrays of the iterations are float32 (half the memory
    traffic; weights need no more digits); the 3×3 systems are solved in
    float64, and so is the final fit with these weights. Distant lamps (one
    light matrix) run compiled (:func:`irls_fit`, whose sums are dropped
    here); near lamps, with a light vector per pixel, run the same steps in
    numpy.
    """
    options = {
        "shadow_fraction": shadow_fraction,
        "highlight_fraction": highlight_fraction,
        "iterations": iterations,
        "max_condition": max_condition,
    }
    if lights.ndim == 2:
        return irls_fit(grey[None], grey, usable, lights, **options)[0]
    return _irls_weights_stepwise(grey, usable, lights, **options)


def irls_fit(
    planes: np.ndarray,
    grey: np.ndarray,
    usable: np.ndarray,
    lights: np.ndarray,
    *,
    shadow_fraction: float,
    highlight_fraction: float,
    iterations: int,
    max_condition: float,
) -> tuple[np.ndarray, tuple]:
    """IRLS weights with one light matrix, and the sums of the fit with them, compiled.

    Parameters
    ----------
    planes : (C, L, n) float64
        Observations per channel (grey: ``grey[None]``).
    grey : (L, n) float32 or float64
        The observations reweighted (colour: the mean over channels).
    usable : (L, n) bool
    lights : (L, 3) float64

    Returns
    -------
    weights : (L, n) float32
    sums : tuple
        ``upper`` (6, n) ``Σ w s_i s_j``, ``moment`` (C, 3, n) ``Σ w I s``,
        ``energy`` (C, n) ``Σ w I²``, ``weight_sum`` (n,) and ``used`` (n,),
        float64, as :func:`._kernels.weighted_sums` gives them.
    """
    n_lights, n = grey.shape
    weights = np.empty(grey.shape, np.float32)
    sums = sum_arrays(n, planes.shape[0])
    settings = np.array(
        [shadow_fraction, iterations, max_condition, TUKEY_C, _MAD_TO_SIGMA, _SCALE_FLOOR]
    )
    irls_fit_kernel(
        np.ascontiguousarray(grey),
        np.ascontiguousarray(usable),
        lights.astype(np.float32),
        n_lights - 1 - highlight_count(n_lights, highlight_fraction),
        settings,
        weights,
        np.ascontiguousarray(planes, dtype=np.float64),
        np.ascontiguousarray(lights, dtype=np.float64),
        sums,
    )
    return weights, sums


def _irls_weights_stepwise(
    grey, usable, lights, *, shadow_fraction, highlight_fraction, iterations, max_condition
) -> np.ndarray:
    """:func:`irls_weights` with a light vector per pixel (L, n, 3), in numpy."""
    ref = reference_level(grey, highlight_fraction)
    support = usable & (grey >= shadow_fraction * ref)
    weights = (support & (grey <= ref)).astype(np.float32)
    floor = _SCALE_FLOOR * np.maximum(ref, 0.0)
    grey32 = grey.astype(np.float32)
    lights32 = lights.astype(np.float32)
    shadow_level = (shadow_fraction * ref).astype(np.float32)
    for _ in range(iterations):
        a = _system.normal_matrix(lights32, weights).astype(np.float64)
        ok = _system.condition(a) <= max_condition
        g = _system.moment(lights32, weights, grey32).astype(np.float64)
        b = _system.solve_sym3(a, g, ok).astype(np.float32)
        predicted = _system.predict(lights32, b)
        # |residual| in place: the biweight below needs only its square.
        residual = np.subtract(grey32, predicted)
        np.abs(residual, out=residual)
        scale = np.maximum(_MAD_TO_SIGMA * _median(residual, weights > 0), floor)
        inverse = np.divide(1.0, TUKEY_C * scale, out=np.zeros_like(scale), where=scale > 0)
        u = np.multiply(residual, inverse.astype(np.float32), out=residual)
        # Tukey's biweight (1 − u²)²₊ with u = residual / (c · scale), in place.
        u2 = np.square(u, out=u)
        tukey = np.square(np.clip(np.subtract(1.0, u2, out=u2), 0.0, None, out=u2), out=u2)
        # An observation the current fit puts in attached shadow carries no information.
        weights = np.multiply(tukey, support & (predicted > shadow_level), out=tukey)
    return weights


def _median(magnitude: np.ndarray, support: np.ndarray) -> np.ndarray:
    """Per-pixel median of ``magnitude`` (L, n), ≥ 0, over the supported observations.

    0 where a pixel has none. Sorted pixel by pixel in contiguous float32 rows
    (sorting along the light axis of the (L, n) layout is 5–10× slower; the
    scale needs no more than float32's digits). Dividing by ``support`` masks,
    converts and transposes in one pass: unsupported entries become inf or
    NaN, which both sort last.
    """
    n_lights, n = magnitude.shape
    rows = np.empty((n, n_lights), np.float32)
    with np.errstate(divide="ignore", invalid="ignore"):
        np.divide(magnitude, support, out=rows.T, casting="same_kind")
    rows.sort(axis=1)
    count = support.sum(axis=0)
    lower = np.clip((count - 1) // 2, 0, None)
    upper = np.clip(count // 2, 0, None)
    lo = np.take_along_axis(rows, lower[:, None], axis=1)[:, 0]
    hi = np.take_along_axis(rows, upper[:, None], axis=1)[:, 0]
    median = 0.5 * (lo.astype(np.float64) + hi)
    return np.where(count > 0, median, 0.0)
