"""Sub-pixel (or sub-frame) peak location from samples around a discrete maximum.

Three detectors, selectable by name, all working on a window of samples
centred on the discrete maximum, vectorised over any number of profiles:

``"centroid"``
    Centre of mass of the 5 samples around the maximum, window minimum
    subtracted.
``"gaussian"``
    Parabola through the logarithms of the 3 samples around the maximum: exact
    for a Gaussian profile without background.
``"blais_rioux"``
    Zero crossing of the 4th-order derivative filter
    ``g(i) = f(i-2) + f(i-1) - f(i+1) - f(i+2)``, linearly interpolated
    between the two samples around the maximum (7 samples).

The same detectors find the laser line across image profiles and the time of
peak intensity in the space-time analysis of seed ``001_…`` section 3.2.

References
----------
.. [1] F. Blais, M. Rioux. "Real-time numerical peak detector." Signal
   Processing 11(2), 1986.
.. [2] R. B. Fisher, D. K. Naidu. "A comparison of algorithms for subpixel
   peak detection." Image Technology, Springer 1996.
"""

from __future__ import annotations

from typing import Literal

import numpy as np

from processing.mdf._errors import MdfError

__all__ = ["PEAK_METHODS", "PeakMethod", "peak_offset", "peak_radius"]

PeakMethod = Literal["centroid", "gaussian", "blais_rioux"]

#: Samples needed on each side of the discrete maximum, per detector.
_RADIUS = {"gaussian": 1, "centroid": 2, "blais_rioux": 3}
PEAK_METHODS: tuple[str, ...] = tuple(_RADIUS)

# Log of a non-positive sample: clamp to this fraction of the window's peak.
_LOG_FLOOR = 1e-6


def peak_radius(method: str) -> int:
    """Samples each side of the maximum that ``method`` needs (1, 2 or 3)."""
    try:
        return _RADIUS[method]
    except KeyError:
        raise MdfError(f"peak method {method!r} is unknown; valid are {PEAK_METHODS}") from None


def peak_offset(window, *, method: PeakMethod = "gaussian") -> tuple[np.ndarray, np.ndarray]:
    """Offset of the true peak from the centre sample of each window.

    Parameters
    ----------
    window : (2r+1, ...) array
        Samples along the profile, the discrete maximum at index ``r``, with
        ``r >= peak_radius(method)`` (only the central samples are used).
        Subtract the background first for ``"gaussian"``; ``"centroid"``
        subtracts the window minimum itself.
    method : {"centroid", "gaussian", "blais_rioux"}

    Returns
    -------
    offset : (...) float64
        Peak position minus the centre index, in samples, within [-1, 1];
        0 where the fit failed.
    ok : (...) bool
        False where the window has no usable peak (flat, or not concave).

    Examples
    --------
    >>> x = np.arange(-3, 4) - 0.3
    >>> off, ok = peak_offset(np.exp(-x**2 / 2.0), method="gaussian")
    >>> round(float(off), 6), bool(ok)
    (0.3, True)
    """
    need = peak_radius(method)
    w = np.asarray(window, dtype=np.float64)
    if w.ndim == 0 or w.shape[0] % 2 != 1 or w.shape[0] < 2 * need + 1:
        raise MdfError(
            f"peak_offset: window has {w.shape[:1]} samples along axis 0; method {method!r} "
            f"needs an odd count ≥ {2 * need + 1} with the maximum in the middle"
        )
    r = w.shape[0] // 2
    f = w[r - need : r + need + 1]
    if method == "gaussian":
        offset, ok = _gaussian(f)
    elif method == "centroid":
        offset, ok = _centroid(f)
    else:
        offset, ok = _blais_rioux(f)
    return np.where(ok, np.clip(offset, -1.0, 1.0), 0.0), ok


def _gaussian(f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    floor = np.maximum(f[1], 1e-300) * _LOG_FLOOR
    a, b, c = (np.log(np.maximum(f[i], floor)) for i in range(3))
    denom = a - 2.0 * b + c
    ok = (denom < -1e-12) & (f[1] > 0)
    safe = np.where(ok, denom, -1.0)
    return 0.5 * (a - c) / safe, ok


def _centroid(f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    weights = f - f.min(axis=0)
    total = weights.sum(axis=0)
    ok = total > 0
    pos = np.arange(-2.0, 3.0).reshape((5,) + (1,) * (f.ndim - 1))
    return (pos * weights).sum(axis=0) / np.where(ok, total, 1.0), ok


def _blais_rioux(f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    # g(i) for i = -1, 0, 1 relative to the maximum (f holds samples -3..3).
    g = [f[i - 2] + f[i - 1] - f[i + 1] - f[i + 2] for i in (2, 3, 4)]
    g_m, g_0, g_p = g
    # g < 0 before the peak and > 0 after it: find the sign change.
    right = (g_0 <= 0) & (g_p > 0)
    left = ~right & (g_m < 0) & (g_0 >= 0)
    d_right = -g_0 / np.where(right, g_p - g_0, 1.0)
    d_left = -1.0 - g_m / np.where(left, g_0 - g_m, 1.0)
    return np.where(right, d_right, d_left), right | left
