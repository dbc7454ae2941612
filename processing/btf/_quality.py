"""Error measures of reconstructed textures."""

from __future__ import annotations

import numpy as np

__all__ = ["psnr_db", "rmse"]

#: PSNR reported when the error is exactly zero (finite, so tables stay numeric).
PSNR_CAP_DB = 200.0


def rmse(reconstructed, reference) -> float:
    """Root-mean-square difference, in the textures' units (float64 accumulation)."""
    a = np.asarray(reconstructed, dtype=np.float64)
    b = np.asarray(reference, dtype=np.float64)
    return float(np.sqrt(np.mean((a - b) ** 2)))


def psnr_db(rmse_value: float, *, peak: float) -> float:
    """Peak signal-to-noise ratio 20·log10(peak / RMSE) in dB, capped at 200 dB."""
    if rmse_value <= peak * 10 ** (-PSNR_CAP_DB / 20):
        return PSNR_CAP_DB
    return float(20.0 * np.log10(peak / rmse_value))
