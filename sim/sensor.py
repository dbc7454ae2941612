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
    "standard_normal",
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
    variance (one float32 standard normal per pixel, :func:`standard_normal`);
    below :func:`gaussian_floor_e` electrons the Poisson draw is exact.
    With σ ≥ 3.85 e⁻ every level qualifies.
    """
    gain = full_scale(bit_depth) / full_well_e
    signal = np.ascontiguousarray(signal_dn, dtype=np.float64)
    unit = standard_normal(rng, signal.shape)
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


# The ziggurat of Marsaglia & Tsang (2000) with 256 layers on 23-bit magnitudes, as numpy's
# float32 normal lays it out: layer i spans x < X_i; a draw inside the layer's rectangle
# under the curve is accepted at once (99 % of them), the rest are tested against the density,
# and layer 0 carries the tail beyond R.
_ZIG_R = 3.6541528853610088
_ZIG_AREA = 0.00492867323399
_ZIG_ONE = float(1 << 23)


def _ziggurat_tables() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """ki (acceptance bound on the 23-bit magnitude), wi (its scale to x), fi (density)
    of each layer, 256 each."""
    ki, wi, fi = np.zeros(256, np.uint32), np.zeros(256), np.zeros(256)
    x = previous = _ZIG_R
    q = _ZIG_AREA / math.exp(-0.5 * x * x)
    ki[0], wi[0], fi[0] = int(x / q * _ZIG_ONE), q / _ZIG_ONE, 1.0
    wi[255], fi[255] = x / _ZIG_ONE, math.exp(-0.5 * x * x)
    for i in range(254, 0, -1):
        x = math.sqrt(-2.0 * math.log(_ZIG_AREA / x + math.exp(-0.5 * x * x)))
        ki[i + 1] = int(x / previous * _ZIG_ONE)
        previous = x
        fi[i], wi[i] = math.exp(-0.5 * x * x), x / _ZIG_ONE
    return ki, wi.astype(np.float32), fi.astype(np.float32)


_KI, _WI, _FI = _ziggurat_tables()


def standard_normal(rng: np.random.Generator, shape) -> np.ndarray:
    """float32 standard normals of ``shape``, drawn by a compiled ziggurat from the raw
    64-bit output of ``rng``'s bit generator (each word as two 32-bit ones).

    The law of ``rng.standard_normal(shape, dtype=np.float32)``, numpy's float32
    ziggurat with the same layers (which fetches each word through a function
    pointer), in less than half its time; mostly its values too, not all (the tables
    here are computed, and a few of their last bits differ from numpy's). The
    generator advances by the words drawn, a few more than the values take.
    """
    out = np.empty(int(np.prod(shape)), dtype=np.float32)
    done = 0
    while done < out.size:
        # ≈ 1.02 words a value (rejections draw again); any shortfall, in another round.
        words = rng.bit_generator.random_raw((out.size - done) * 52 // 100 + 64).view(np.uint32)
        done = _ziggurat(words, out, done, _KI, _WI, _FI, _ZIG_R)
    return out.reshape(shape)


@njit(cache=True, nogil=True)
def _ziggurat(words, out, start, ki, wi, fi, r):
    """Fill ``out[start:]`` from ``words``; the index reached (short of the end when
    the words ran out)."""
    k = 0
    n = words.size
    for i in range(start, out.size):
        while True:
            if k >= n:
                return i
            w = words[k]
            k += 1
            layer = w & 0xFF
            magnitude = (w >> 9) & 0x7FFFFF
            x = np.float32(magnitude * wi[layer])
            if (w >> 8) & 1:
                x = -x
            if magnitude < ki[layer]:
                out[i] = x
                break
            if layer == 0:  # the tail beyond r: Marsaglia's method, repeated until it accepts
                tail = -1.0
                while tail < 0 and k + 2 <= n:
                    u1 = (words[k] >> 8) / 16777216.0  # 24-bit uniforms in [0, 1)
                    u2 = (words[k + 1] >> 8) / 16777216.0
                    k += 2
                    xx = -math.log1p(-u1) / r
                    if -2.0 * math.log1p(-u2) > xx * xx:
                        tail = r + xx
                if tail < 0:
                    return i
                out[i] = -tail if (magnitude >> 8) & 1 else tail
                break
            else:
                if k + 1 > n:
                    return i
                u = (words[k] >> 8) / 16777216.0
                k += 1
                if (fi[layer - 1] - fi[layer]) * u + fi[layer] < math.exp(-0.5 * x * x):
                    out[i] = x
                    break
    return out.size


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
