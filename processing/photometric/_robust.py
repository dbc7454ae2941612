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
    float64, and so is the final fit with these weights. Compiled
    (:func:`irls_fit`, whose sums are dropped here) for one light matrix
    (L, 3) and for a light vector per pixel (L, n, 3).
    """
    options = {
        "shadow_fraction": shadow_fraction,
        "highlight_fraction": highlight_fraction,
        "iterations": iterations,
        "max_condition": max_condition,
    }
    if lights.ndim == 3:  # (L, n, 3) → x, y, z planes (3, L, n)
        lights = np.ascontiguousarray(np.moveaxis(lights, 2, 0))
    return irls_fit(grey[None], grey, usable, lights, **options)[0]


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
    """IRLS weights and the sums of the fit with them, compiled.

    Parameters
    ----------
    planes : (C, L, n) float64
        Observations per channel (grey: ``grey[None]``).
    grey : (L, n) float32 or float64
        The observations reweighted (colour: the mean over channels).
    usable : (L, n) bool
    lights : (L, 3) float64, or (3, L, n) float64
        One light matrix, or a light vector per pixel as x, y, z planes
        (near lamps).

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
