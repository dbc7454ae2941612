"""The space-time tracker's per-scan result, compiled (numba, cached on disk).

One pass over the pixels: contrast, reason and, for every lit pixel with a
complete window, the sub-frame offset of its peak. The detectors are those of
:mod:`processing.mdf.peaks`, per pixel and in the same float64 arithmetic
(tests compare the two on windows with ties, dark samples and peaks at the
sequence edges); the numpy version gathered the windows, converted them to
float64 and took three logarithms per pixel, at 9–15 reads of a 120-frame
sequence. Integer frames look their logarithms up in a table built with
``np.log`` (the samples above the background are whole numbers).
"""

from __future__ import annotations

import math
from functools import cache

import numpy as np
from numba import njit

from processing._numba_cache import keep_fresh
from processing.mdf import _reason
from processing.mdf._reason import Reason

#: Detector codes of :func:`fit_peaks`.
METHOD_CODES = {"gaussian": 0, "centroid": 1, "blais_rioux": 2}

_OK = np.uint8(Reason.OK)
_UNLIT = np.uint8(Reason.UNLIT)
_EDGE = np.uint8(Reason.AT_SEQUENCE_EDGE)
_FAILED = np.uint8(Reason.FIT_FAILED)
# As processing.mdf.peaks: a non-positive sample's log is clamped to this fraction of the peak's.
_LOG_FLOOR = 1e-6


@cache
def log_table(dtype: np.dtype) -> np.ndarray:
    """``np.log`` of every whole sample value of an integer dtype (empty for floats)."""
    if not np.issubdtype(dtype, np.integer):
        return np.zeros(0)
    with np.errstate(divide="ignore"):
        return np.log(np.arange(np.iinfo(dtype).max + 1, dtype=np.float64))


@njit(cache=True, nogil=True)
def fit_peaks(window, best, low, index, held, frames, r, min_contrast, method, logs,
              time, contrast, reason):  # fmt: skip
    """Fill ``time``, ``contrast`` and ``reason`` (each (N,)) from the running state.

    window : (N, 2r + 1) the samples around frame ``held`` (int32, -1: none);
    best, low : (N,) running maximum and minimum; index : (N,) int32 frame of
    the maximum; frames : frames seen; r : the window's radius; min_contrast :
    float32 threshold; method : a :data:`METHOD_CODES` value; logs :
    :func:`log_table` of the frames' dtype.
    """
    for p in range(best.shape[0]):
        floor_p = np.float32(low[p])
        c = np.float32(best[p]) - floor_p
        contrast[p] = c
        time[p] = -1.0
        if not c >= min_contrast:
            reason[p] = _UNLIT
            continue
        at = index[p]
        if held[p] != at or at < r or at > frames - 1 - r:
            reason[p] = _EDGE
            continue
        # Samples above the background as float64 scalars (no array: kept in registers).
        w, fl = window[p], np.float64(floor_p)
        if method == 0:
            offset, ok = _gaussian(w[r - 1] - fl, w[r] - fl, w[r + 1] - fl, logs)
        elif method == 1:
            offset, ok = _centroid(w[r - 2] - fl, w[r - 1] - fl, w[r] - fl, w[r + 1] - fl,
                                   w[r + 2] - fl)  # fmt: skip
        else:
            offset, ok = _blais_rioux(w[r - 3] - fl, w[r - 2] - fl, w[r - 1] - fl, w[r] - fl,
                                      w[r + 1] - fl, w[r + 2] - fl, w[r + 3] - fl)  # fmt: skip
        if ok:
            reason[p] = _OK
            time[p] = np.float32(at + min(max(offset, -1.0), 1.0))
        else:
            reason[p] = _FAILED


@njit(cache=True, nogil=True, inline="always")
def _log(v, floor, logs):
    if logs.shape[0] > 0 and v >= 1.0:
        return logs[int(v)]
    return math.log(max(v, floor))


@njit(cache=True, nogil=True, inline="always")
def _gaussian(f0, f1, f2, logs):
    floor = max(f1, 1e-300) * _LOG_FLOOR
    a, b, c = _log(f0, floor, logs), _log(f1, floor, logs), _log(f2, floor, logs)
    denom = a - 2.0 * b + c
    if denom < -1e-12 and f1 > 0:
        return 0.5 * (a - c) / denom, True
    return 0.0, False


@njit(cache=True, nogil=True, inline="always")
def _centroid(f0, f1, f2, f3, f4):
    lowest = min(f0, f1, f2, f3, f4)
    w0, w1, w2, w3, w4 = f0 - lowest, f1 - lowest, f2 - lowest, f3 - lowest, f4 - lowest
    # Summed in numpy's order (first sample first), so the values match it exactly.
    total = w0 + w1 + w2 + w3 + w4
    moment = -2.0 * w0 + -1.0 * w1 + 0.0 * w2 + 1.0 * w3 + 2.0 * w4
    if total > 0:
        return moment / total, True
    return 0.0, False


@njit(cache=True, nogil=True, inline="always")
def _blais_rioux(f0, f1, f2, f3, f4, f5, f6):
    # g(i) = f(i-2) + f(i-1) - f(i+1) - f(i+2) at i = -1, 0, 1 (f0..f6 are samples -3..3).
    g_m = f0 + f1 - f3 - f4
    g_0 = f1 + f2 - f4 - f5
    g_p = f2 + f3 - f5 - f6
    if g_0 <= 0 and g_p > 0:
        return -g_0 / (g_p - g_0), True
    if g_m < 0 and g_0 >= 0:
        return -1.0 - g_m / (g_0 - g_m), True
    return 0.0, False


keep_fresh(__name__, _reason)
