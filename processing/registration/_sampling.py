"""Bilinear samples of a frame averaged over each texel's sub-samples, in one compiled pass.

:func:`~processing.registration._rectify.rectify` box-filters every texel from
s_x × s_y bilinear samples per channel. As ``scipy.ndimage.map_coordinates``
calls (one per channel, on float64 copies of the planes) and a mean over the
sub-samples, that took half of a frame's registration; here the frame is read
in its own dtype, all channels at once, and the mean is summed as the samples
are taken. ``map_coordinates(order=1, mode="nearest")``'s values, to rounding.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["box_bilinear", "homography_footprint_px", "kernel_frame", "project_box_bilinear"]


def kernel_frame(frame: np.ndarray) -> np.ndarray:
    """``frame`` in a dtype the compiled passes read: native byte order (a frame read from a
    big-endian file is swapped), float16 as float32, bool as uint8; otherwise the same array."""
    image = np.asarray(frame)
    if image.dtype == np.float16:
        return image.astype(np.float32)
    if image.dtype == np.bool_:
        return image.astype(np.uint8)
    if not image.dtype.isnative:
        return image.astype(image.dtype.newbyteorder("="))
    return image


def box_bilinear(frame: np.ndarray, pixels: np.ndarray, n_sub: int, out: np.ndarray) -> None:
    """Fill ``out`` (n, C) float64 with the mean bilinear value of each run of sub-samples.

    Parameters
    ----------
    frame : (H, W, C) array, integer or float, H, W ≥ 2
        The raw frame.
    pixels : (n · n_sub, 2) float64
        Sample positions (x = column, y = row, pixel centres at integers), the
        ``n_sub`` of texel t at rows ``t · n_sub … (t + 1) · n_sub − 1``. Outside
        the frame the nearest edge pixel's value is taken; a non-finite position
        reads pixel (0, 0) (its texel lies outside and is marked invalid by the caller).
    n_sub : int
        Sub-samples per texel, ≥ 1.
    out : (n, C) float64, C-contiguous, zeros
        The texels' mean values are written in place.
    """
    pixels = np.ascontiguousarray(pixels, dtype=np.float64)
    _box_bilinear(kernel_frame(frame), pixels, int(n_sub), out)


def project_box_bilinear(
    frame: np.ndarray,
    plane_to_image: np.ndarray,
    centers_mm: np.ndarray,
    sub_mm: np.ndarray,
    out: np.ndarray,
    valid: np.ndarray,
) -> None:
    """:func:`box_bilinear` at texel centres + sub-sample offsets mapped through a homography.

    For a camera without lens distortion the sample positions are the homography's
    alone, so they are computed as they are sampled (no (n · n_sub, 2) arrays).

    Parameters
    ----------
    frame : (H, W, C) array, integer or float, H, W ≥ 2
    plane_to_image : (3, 3) float64
        Plate (x_mm, y_mm, 1) → pixels (x = column, y = row).
    centers_mm : (n, 2) float64
        Texel centres on the plate.
    sub_mm : (n_sub, 2) float64
        Sub-sample offsets from a texel's centre.
    out : (n, C) float64 or float32, C-contiguous
        The texels' mean values are written in place (summed in float64).
    valid : (n,) bool
        Set False (never True) where a sub-sample lies outside the frame's
        pixel area ``[−0.5, W − 0.5] × [−0.5, H − 0.5]``.
    """
    _project_box_bilinear(
        kernel_frame(frame), np.ascontiguousarray(plane_to_image, dtype=np.float64),
        np.ascontiguousarray(centers_mm, dtype=np.float64),
        np.ascontiguousarray(sub_mm, dtype=np.float64), out, valid,
    )  # fmt: skip


def homography_footprint_px(
    plane_to_image: np.ndarray, centers_mm: np.ndarray, step_mm: float
) -> tuple[float, float]:
    """Largest extent in pixels of one texel step along x and along y over the texel
    centres (n, 2), mapped through the homography alone (a camera without lens distortion)."""
    extents = np.zeros(2)
    _footprint(
        np.ascontiguousarray(plane_to_image, dtype=np.float64),
        np.ascontiguousarray(centers_mm, dtype=np.float64), float(step_mm), extents,
    )  # fmt: skip
    return float(extents[0]), float(extents[1])


@njit(cache=True, nogil=True)
def _box_bilinear(frame, pixels, n_sub, out):
    for t in range(out.shape[0]):
        s0 = s1 = s2 = 0.0
        for k in range(t * n_sub, (t + 1) * n_sub):
            v0, v1, v2 = _bilinear(frame, pixels[k, 0], pixels[k, 1])
            s0, s1, s2 = s0 + v0, s1 + v1, s2 + v2
        _store(out, t, s0, s1, s2, n_sub)


@njit(cache=True, nogil=True)
def _project_box_bilinear(frame, H, centers, sub, out, valid):
    rows, cols = frame.shape[0], frame.shape[1]
    n_sub = sub.shape[0]
    # H (c + o) = H c + H (o, 0): the sub-samples' offsets through H's linear part, once.
    shift = np.empty((n_sub, 3))
    for k in range(n_sub):
        for a in range(3):
            shift[k, a] = H[a, 0] * sub[k, 0] + H[a, 1] * sub[k, 1]
    for t in range(out.shape[0]):
        cx, cy = centers[t, 0], centers[t, 1]
        bx = H[0, 0] * cx + H[0, 1] * cy + H[0, 2]
        by = H[1, 0] * cx + H[1, 1] * cy + H[1, 2]
        bw = H[2, 0] * cx + H[2, 1] * cy + H[2, 2]
        inside = True
        s0 = s1 = s2 = 0.0
        for k in range(n_sub):
            w = 1.0 / (bw + shift[k, 2])
            x, y = (bx + shift[k, 0]) * w, (by + shift[k, 1]) * w
            inside &= (x >= -0.5) & (x <= cols - 0.5) & (y >= -0.5) & (y <= rows - 0.5)
            v0, v1, v2 = _bilinear(frame, x, y)
            s0, s1, s2 = s0 + v0, s1 + v1, s2 + v2
        if not inside:
            valid[t] = False
        _store(out, t, s0, s1, s2, n_sub)


@njit(cache=True, nogil=True)
def _footprint(H, centers, step, extents):
    for t in range(centers.shape[0]):
        x, y = _project(H, centers[t, 0], centers[t, 1])
        ax, ay = _project(H, centers[t, 0] + step, centers[t, 1])
        bx, by = _project(H, centers[t, 0], centers[t, 1] + step)
        extents[0] = max(extents[0], (ax - x) ** 2 + (ay - y) ** 2)
        extents[1] = max(extents[1], (bx - x) ** 2 + (by - y) ** 2)
    extents[0] = math.sqrt(extents[0])
    extents[1] = math.sqrt(extents[1])


@njit(cache=True, nogil=True, inline="always")
def _project(H, px, py):
    """Pixel (x, y) of plate point (px, py) mm: ``_to_pixels``' arithmetic, term by term."""
    w = H[2, 0] * px + H[2, 1] * py + H[2, 2]
    return (H[0, 0] * px + H[0, 1] * py + H[0, 2]) / w, (H[1, 0] * px + H[1, 1] * py + H[1, 2]) / w


@njit(cache=True, nogil=True, inline="always")
def _bilinear(frame, x, y):
    """The bilinear value at (x, y) of channels 0, 1, 2 (0.0 past the frame's C); outside,
    the nearest edge pixel's; a non-finite position reads pixel (0, 0). Summed in local
    accumulators by the callers: added into ``out`` per sample, the sums went through memory."""
    rows, cols = frame.shape[0], frame.shape[1]
    if not (x - x == 0.0 and y - y == 0.0):
        x = y = 0.0
    x = min(max(x, 0.0), cols - 1.0)
    y = min(max(y, 0.0), rows - 1.0)
    c0 = min(int(x), cols - 2)
    r0 = min(int(y), rows - 2)
    fx, fy = x - c0, y - r0
    v0 = _lerp2(frame, r0, c0, 0, fx, fy)
    if frame.shape[2] == 1:
        return v0, 0.0, 0.0
    return v0, _lerp2(frame, r0, c0, 1, fx, fy), _lerp2(frame, r0, c0, 2, fx, fy)


@njit(cache=True, nogil=True, inline="always")
def _lerp2(frame, r0, c0, c, fx, fy):
    """Channel c bilinear between pixels (r0, c0) and (r0 + 1, c0 + 1) at fractions fx, fy."""
    top = (1.0 - fx) * frame[r0, c0, c] + fx * frame[r0, c0 + 1, c]
    bottom = (1.0 - fx) * frame[r0 + 1, c0, c] + fx * frame[r0 + 1, c0 + 1, c]
    return (1.0 - fy) * top + fy * bottom


@njit(cache=True, nogil=True, inline="always")
def _store(out, t, s0, s1, s2, n_sub):
    """``out[t]`` = the sums of texel t's sub-samples / ``n_sub`` (C ∈ {1, 3})."""
    out[t, 0] = s0 / n_sub
    if out.shape[1] == 3:
        out[t, 1] = s1 / n_sub
        out[t, 2] = s2 / n_sub
