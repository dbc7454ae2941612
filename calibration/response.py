"""Radiometric response from HDR exposure brackets (Debevec & Malik, via OpenCV).

An 8-bit camera's pixel values are a non-linear function of exposure; the
response curve maps them back to linear radiance. It is recovered from a
bracket of exposures of a static scene, and then merges brackets into linear
radiance maps with a per-pixel validity (a pixel saturated or dark in every
exposure has no trustworthy value).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

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


def calibrate_response(images, exposures_s, *, samples: int = 500, smoothness: float = 20.0):
    """Recover the inverse response curve from an exposure bracket.

    Parameters
    ----------
    images : sequence of (H, W, C) uint8
        The same static scene at different exposures (C = 3, as OpenCV needs).
    exposures_s : (k,) float
        Exposure time of each image, seconds, distinct, k ≥ 2.

    References
    ----------
    .. [1] Debevec & Malik, "Recovering high dynamic range radiance maps from
       photographs", SIGGRAPH 1997.
    """
    imgs, times = _check_bracket(images, exposures_s)
    if imgs[0].shape[-1] != 3:
        raise ResponseError(f"OpenCV's Debevec calibration needs 3 channels, got {imgs[0].shape}")
    calib = cv2.createCalibrateDebevec(samples=samples, lambda_=smoothness, random=False)
    curve = calib.process(imgs, times.astype(np.float32)).reshape(256, -1).astype(np.float64)
    curve = np.maximum(curve, np.finfo(np.float32).tiny)
    curve /= curve[128]
    return ResponseCurve(curve.astype(np.float32))


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
