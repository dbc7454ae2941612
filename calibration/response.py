"""Radiometric response from HDR exposure brackets (Debevec & Malik, via OpenCV).

An 8-bit camera's pixel values are a non-linear function of exposure; the
response curve maps them back to linear radiance. It is recovered from a
bracket of exposures of a static scene, and then merges brackets into linear
radiance maps with a per-pixel validity (a pixel saturated or dark in every
exposure has no trustworthy value).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import lil_matrix
from scipy.sparse.linalg import lsqr

from rig.errors import RigError

__all__ = ["Radiance", "ResponseCurve", "ResponseError", "calibrate_response", "merge_bracket"]


class ResponseError(RigError):
    """The exposure bracket cannot give a response curve or a radiance map."""


@dataclass(frozen=True)
class ResponseCurve:
    """Per-channel inverse response: ``curve[v, c]`` is the relative exposure
    that produces value v in channel c, normalised so that ``curve[128] = 1``.
    """

    curve: np.ndarray  # (256, C) float32

    def linearize(self, image: np.ndarray) -> np.ndarray:
        """(H, W, C) uint8 → (H, W, C) float32 relative exposure."""
        image = _check_uint8(image, "image")
        channels = np.arange(image.shape[-1])
        return self.curve[image, channels].astype(np.float32)


@dataclass(frozen=True)
class Radiance:
    """A merged radiance map with its validity.

    radiance : (H, W, C) float32, relative units per second of exposure
    valid : (H, W) bool — False where every exposure was saturated or dark
    saturated, dark : (H, W) bool — the reasons
    """

    radiance: np.ndarray
    valid: np.ndarray
    saturated: np.ndarray
    dark: np.ndarray


def _check_uint8(image, name: str) -> np.ndarray:
    a = np.asarray(image)
    if a.dtype != np.uint8 or a.ndim != 3:
        raise ResponseError(f"{name}: expected (H, W, C) uint8, got {a.dtype} {a.shape}")
    return a


def _check_bracket(images, exposures_s) -> tuple[list[np.ndarray], np.ndarray]:
    imgs = [_check_uint8(im, f"images[{i}]") for i, im in enumerate(images)]
    times = np.asarray(exposures_s, dtype=np.float64).ravel()
    if len(imgs) != len(times):
        raise ResponseError(f"{len(imgs)} images but {len(times)} exposure times")
    if len(imgs) < 2:
        raise ResponseError(
            f"an exposure bracket needs at least 2 exposures, got {len(imgs)}; "
            "the response curve is not observable from one"
        )
    if not np.all(np.isfinite(times)) or np.any(times <= 0):
        raise ResponseError(f"exposure times must be finite and > 0, got {times.tolist()}")
    if len(np.unique(times)) != len(times):
        raise ResponseError(f"exposure times must be distinct, got {times.tolist()}")
    if len({im.shape for im in imgs}) != 1:
        raise ResponseError("all images of a bracket must have the same shape")
    return imgs, times


def calibrate_response(images, exposures_s, *, samples: int = 300, smoothness: float = 30.0):
    """Recover the inverse response curve from an exposure bracket (Debevec & Malik).

    The least-squares problem of [1]_ — ``w(Z)·(g(Z) − ln E_i − ln t_j) = 0`` over
    sample pixels *i* and exposures *j*, ``λ·w(z)·g''(z) = 0``, ``g(128) = 0`` —
    solved per channel in float64. The sample pixels are chosen so that their
    values in the middle exposure spread evenly over 0…255: OpenCV's
    ``CalibrateDebevec`` takes a regular grid of pixels, which on a calibration
    target (mostly black and white) leaves the middle values with few samples
    and the curve off by 4–12 % there.

    Parameters
    ----------
    images : sequence of (H, W, C) uint8
        The same static scene at different exposures.
    exposures_s : (k,) float
        Exposure time of each image, seconds, distinct, k ≥ 2.
    samples : pixels sampled per channel
    smoothness : λ, the weight of the curvature penalty

    References
    ----------
    .. [1] Debevec & Malik, "Recovering high dynamic range radiance maps from
       photographs", SIGGRAPH 1997.
    """
    imgs, times = _check_bracket(images, exposures_s)
    stack = np.stack(imgs).reshape(len(imgs), -1, imgs[0].shape[-1])  # (k, pixels, C)
    curve = np.empty((256, stack.shape[-1]))
    for c in range(stack.shape[-1]):
        curve[:, c] = _gsolve(stack[:, :, c], np.log(times), samples, smoothness)
    return ResponseCurve(np.exp(curve - curve[128]).astype(np.float32))


def _hat(z: np.ndarray) -> np.ndarray:
    # Zero at 0 and 255: a clipped value says only that the exposure was beyond.
    return np.minimum(z, 255 - z).astype(np.float64)


def _gsolve(values: np.ndarray, log_t: np.ndarray, samples: int, smoothness: float):
    """g(0…255) for one channel; ``values`` (k, pixels) uint8."""
    middle = values[len(values) // 2]
    picks = []
    for level in np.linspace(0, 255, samples):
        candidates = np.flatnonzero(np.abs(middle.astype(np.int64) - level) < 0.5 + 255 / samples)
        if len(candidates):
            picks.append(candidates[len(candidates) // 2])
    picks = np.unique(picks)
    # A pixel dark or saturated in every exposure says nothing about the curve.
    useful = picks[(values[:, picks].max(axis=0) > 4) & (values[:, picks].min(axis=0) < 251)]
    if len(useful) < 16:
        raise ResponseError(
            f"only {len(useful)} sample pixels vary over the bracket; the scene needs "
            "more shades (or the exposures are all dark or all saturated)"
        )
    z = values[:, useful]  # (k, n)
    k, n = z.shape
    rows = k * n + 254 + 1
    A = lil_matrix((rows, 256 + n))
    b = np.zeros(rows)
    w = _hat(z)
    r = 0
    for j in range(k):
        for i in range(n):
            A[r, z[j, i]] = w[j, i]
            A[r, 256 + i] = -w[j, i]
            b[r] = w[j, i] * log_t[j]
            r += 1
    for v in range(1, 255):
        weight = smoothness * _hat(np.array(v))
        A[r, v - 1], A[r, v], A[r, v + 1] = weight, -2 * weight, weight
        r += 1
    A[r, 128] = 1.0
    g = lsqr(A.tocsr(), b, atol=1e-12, btol=1e-12, iter_lim=20000)[0][:256]
    return g


def merge_bracket(
    images,
    exposures_s,
    response: ResponseCurve,
    *,
    dark_level: int = 4,
    saturation_level: int = 250,
) -> Radiance:
    """Merge a bracket into linear radiance with a hat weighting; flag bad pixels.

    A value counts only when ``dark_level < v < saturation_level``; a pixel with
    no counting value in any exposure is invalid (radiance 0) and flagged as
    saturated (its values were all high) or dark.
    """
    imgs, times = _check_bracket(images, exposures_s)
    stack = np.stack(imgs).astype(np.int32)  # (k, H, W, C)
    mid = (dark_level + saturation_level) / 2
    usable = (stack > dark_level) & (stack < saturation_level)
    weight = np.where(usable, 1.0 - np.abs(stack - mid) / (mid - dark_level + 1), 0.0)
    channels = np.arange(stack.shape[-1])
    exposure = response.curve[stack, channels].astype(np.float64)  # relative exposure
    radiance_k = exposure / times[:, None, None, None]
    wsum = weight.sum(axis=0)
    merged = np.where(wsum > 0, (weight * radiance_k).sum(axis=0) / np.maximum(wsum, 1e-12), 0.0)
    valid = np.all(wsum > 0, axis=-1)
    saturated = ~valid & np.any(stack >= saturation_level, axis=(0, -1))
    dark = ~valid & ~saturated
    merged[~valid] = 0.0
    return Radiance(merged.astype(np.float32), valid, saturated, dark)
