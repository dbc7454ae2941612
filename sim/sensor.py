"""The camera's lens and sensor, applied to the rendered optical image.

Pure functions of arrays, one per effect: vignetting, Brown–Conrady lens
distortion, shot + read noise, saturation, the camera's tone curve
(response), quantisation. Units: the signal is
in digital numbers (DN) of the camera's bit depth, full scale ``2**bits − 1``.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from numba import njit
from scipy.optimize import brentq

from rig.camera import PinholeCamera

__all__ = [
    "add_noise",
    "apply_response",
    "distort",
    "distortion_maps",
    "full_scale",
    "gaussian_floor_e",
    "inverse_response",
    "quantize",
    "vignetting_factor",
]


def full_scale(bit_depth: int) -> int:
    """Largest pixel value of a sensor with ``bit_depth`` bits."""
    return 2**bit_depth - 1


def vignetting_factor(camera: PinholeCamera, exponent: float) -> np.ndarray:
    """(H, W) float64 relative irradiance ``cos(α)^exponent`` of each pixel.

    α is the angle between the pixel's pinhole ray and the optical axis
    (exponent 4 is the natural cos⁴ law).
    """
    u, v = np.meshgrid(np.arange(camera.width), np.arange(camera.height))
    x = (u - camera.K[0, 2]) / camera.K[0, 0]
    y = (v - camera.K[1, 2]) / camera.K[1, 1]
    cos_a = 1.0 / np.sqrt(1.0 + x * x + y * y)
    return cos_a**exponent


def distortion_maps(camera: PinholeCamera) -> tuple[np.ndarray, np.ndarray]:
    """cv2.remap maps taking a pinhole image to the distorted camera image.

    Each output pixel's ray (``camera.rays``, which inverts Brown–Conrady)
    is projected with the same camera without distortion; so a world point
    lands where ``camera.project`` says.
    """
    u, v = np.meshgrid(np.arange(camera.width), np.arange(camera.height))
    pix = np.column_stack([u.ravel(), v.ravel()]).astype(np.float64)
    _, dirs = camera.rays(pix)
    d_cam = dirs @ camera.R.T
    xn = d_cam[:, :2] / d_cam[:, 2:3]
    src = xn @ camera.K[:2, :2].T + camera.K[:2, 2]
    shape = (camera.height, camera.width)
    return src[:, 0].reshape(shape).astype(np.float32), src[:, 1].reshape(shape).astype(np.float32)


def distort(image: np.ndarray, maps: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """Warp a pinhole image (H, W[, C]) float through ``distortion_maps``."""
    return cv2.remap(
        image.astype(np.float32), maps[0], maps[1], cv2.INTER_LINEAR,
        borderMode=cv2.BORDER_CONSTANT, borderValue=0,
    )  # fmt: skip


# Largest skewness of a pixel's shot + read noise drawn as one Gaussian. Its CDF then
# differs from the exact one by at most ≈ 0.0665 · skewness (Edgeworth's first term,
# −γ/6 · He₂(x) φ(x), is largest at the mean): 0.7 % of the probability, a fraction of
# what one quantisation step holds. The mean and the variance are exact either way.
GAUSSIAN_SKEWNESS = 0.1


def add_noise(
    signal_dn: np.ndarray,
    *,
    bit_depth: int,
    full_well_e: float,
    read_noise_e: float,
    rng: np.random.Generator,
) -> np.ndarray:
    """Shot and read noise on a signal in DN; returns float64 DN.

    Electrons ``e = signal · full_well / full_scale``; shot noise is Poisson
    in ``e``, read noise Gaussian with σ = ``read_noise_e``. Hence, before
    quantisation, ``mean = signal`` and ``var = signal·g + (read_noise_e·g)²``
    with ``g = full_scale / full_well`` DN per electron.

    Where the sum's skewness ``e / (e + σ²)^1.5`` is at most
    :data:`GAUSSIAN_SKEWNESS` it is drawn as one Gaussian of that mean and
    variance (one float32 standard normal per pixel, a sixth of the Poisson
    draw's time); below :func:`gaussian_floor_e` electrons the Poisson draw is
    exact. With σ ≥ 3.85 e⁻ every level qualifies.
    """
    gain = full_scale(bit_depth) / full_well_e
    signal = np.ascontiguousarray(signal_dn, dtype=np.float64)
    unit = rng.standard_normal(signal.shape, dtype=np.float32)
    noisy = np.empty(signal.shape)
    _gaussian_dn(signal.reshape(-1), unit.reshape(-1), gain, float(read_noise_e) ** 2,
                 noisy.reshape(-1))  # fmt: skip
    floor = gaussian_floor_e(read_noise_e)
    if floor > 0:
        electrons = np.clip(signal, 0, None) / gain
        low = electrons < floor
        if low.any():
            noisy[low] = (rng.poisson(electrons[low]) + read_noise_e * unit[low]) * gain
    return noisy


@njit(cache=True, nogil=True)
def _gaussian_dn(signal, unit, gain, read_var, out):
    """out = (e + √(e + σ²) · unit) · gain with e = max(signal, 0) / gain, in one pass
    (as numpy's seven passes over the frame it cost as much as the draw)."""
    for i in range(signal.size):
        electrons = max(signal[i], 0.0) / gain
        out[i] = (electrons + math.sqrt(electrons + read_var) * unit[i]) * gain


def gaussian_floor_e(read_noise_e: float) -> float:
    """The electrons above which shot + read noise is drawn as a Gaussian (0: at every level).

    The skewness ``e / (e + σ²)^1.5`` peaks at e = 2σ² with ``0.385 / σ``; where
    that exceeds :data:`GAUSSIAN_SKEWNESS` the floor is the level above the peak
    where it falls back to it (100 e⁻ without read noise).
    """
    var = float(read_noise_e) ** 2
    if var == 0:
        return 1.0 / GAUSSIAN_SKEWNESS**2  # Poisson alone: skewness 1/√e
    if 2 / 3**1.5 / float(read_noise_e) <= GAUSSIAN_SKEWNESS:
        return 0.0
    return float(brentq(lambda e: e / (e + var) ** 1.5 - GAUSSIAN_SKEWNESS, 2 * var, 100.0))


def quantize(signal_dn: np.ndarray, dtype: np.dtype) -> np.ndarray:
    """Round to integers and clip to the storage type's range (never wraps)."""
    info = np.iinfo(dtype)
    rounded = np.rint(signal_dn)
    return np.clip(rounded, info.min, info.max, out=rounded).astype(dtype)


def apply_response(signal_dn: np.ndarray, *, bit_depth: int, gamma: float) -> np.ndarray:
    """The camera's tone curve on a linear signal (DN), clipped to full scale first:
    ``full_scale · (signal / full_scale)^(1/gamma)``; float64."""
    top = full_scale(bit_depth)
    linear = np.clip(np.asarray(signal_dn, dtype=np.float64), 0, top) / top
    return top * linear ** (1.0 / gamma)


def inverse_response(values_dn, *, bit_depth: int, gamma: float) -> np.ndarray:
    """The linear signal (DN) that the tone curve maps to ``values_dn``."""
    top = full_scale(bit_depth)
    return top * (np.asarray(values_dn, dtype=np.float64) / top) ** gamma
