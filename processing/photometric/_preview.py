"""Preview images of photometric maps as uint8 arrays (the CLI writes them as PNG)."""

from __future__ import annotations

import numpy as np

from ._errors import PhotometricError
from ._inputs import check_positive


def normal_map_preview(normals) -> np.ndarray:
    """RGB = (n + 1) / 2 of sample-frame normals: (H, W, 3) uint8."""
    n = np.asarray(normals, dtype=np.float64)
    if n.ndim != 3 or n.shape[2] != 3:
        raise PhotometricError(f"normals: expected shape (H, W, 3), got {n.shape}")
    n = np.clip(np.nan_to_num(n, nan=0.0, posinf=1.0, neginf=-1.0), -1.0, 1.0)
    return np.round((n + 1.0) * 127.5).astype(np.uint8)


def albedo_preview(albedo, *, valid=None, white_percentile: float = 99.0, gamma: float = 2.2):
    """Tone-mapped albedo: (H, W) or (H, W, 3) uint8.

    The ``white_percentile`` of the valid pixels maps to white, then a display
    gamma of ``gamma`` is applied; invalid pixels are black.
    """
    a = np.asarray(albedo, dtype=np.float64)
    if a.ndim not in (2, 3) or (a.ndim == 3 and a.shape[2] != 3):
        raise PhotometricError(f"albedo: expected shape (H, W) or (H, W, 3), got {a.shape}")
    if not 0 < white_percentile <= 100:
        raise PhotometricError(
            f"white_percentile: expected 0 < value ≤ 100, got {white_percentile!r}"
        )
    check_positive(gamma, "gamma")
    use = _mask(valid, a.shape[:2]) & np.all(np.isfinite(a.reshape(*a.shape[:2], -1)), axis=2)
    level = a if a.ndim == 2 else a.max(axis=2)
    white = float(np.percentile(level[use], white_percentile)) if use.any() else 0.0
    if not white > 0:
        return np.zeros(a.shape, np.uint8)
    scaled = np.clip(np.where(use if a.ndim == 2 else use[..., None], a, 0.0) / white, 0.0, 1.0)
    return np.round(255.0 * scaled ** (1.0 / gamma)).astype(np.uint8)


def hillshade_preview(
    height_mm,
    *,
    pitch_mm: float,
    valid=None,
    azimuth_deg: float = 135.0,
    elevation_deg: float = 45.0,
) -> np.ndarray:
    """Shaded relief of a height map under a distant light: (H, W) uint8.

    The light comes from azimuth ``azimuth_deg`` (from +x towards +y, so the
    default 135° is the upper left of an image seen from above) at
    ``elevation_deg`` above the sample plane; invalid pixels are black.
    """
    h = np.asarray(height_mm, dtype=np.float64)
    if h.ndim != 2:
        raise PhotometricError(f"height_mm: expected shape (H, W), got {h.shape}")
    pitch = check_positive(pitch_mm, "pitch_mm")
    if not 0 < elevation_deg <= 90:
        raise PhotometricError(f"elevation_deg: expected 0 < value ≤ 90, got {elevation_deg!r}")
    use = _mask(valid, h.shape) & np.isfinite(h)
    h = np.where(use, h, 0.0)
    d_col = np.gradient(h, axis=1) if h.shape[1] > 1 else np.zeros_like(h)
    d_row = np.gradient(h, axis=0) if h.shape[0] > 1 else np.zeros_like(h)
    p, q = d_col / pitch, -d_row / pitch  # rows run along -y
    az, el = np.deg2rad(azimuth_deg), np.deg2rad(elevation_deg)
    light = np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
    shade = (-p * light[0] - q * light[1] + light[2]) / np.sqrt(1.0 + p * p + q * q)
    return np.where(use, np.round(255.0 * np.clip(shade, 0.0, 1.0)), 0).astype(np.uint8)


def _mask(valid, shape) -> np.ndarray:
    if valid is None:
        return np.ones(shape, bool)
    arr = np.asarray(valid)
    if arr.dtype != np.bool_ or arr.shape != tuple(shape):
        raise PhotometricError(
            f"valid: expected a bool array of shape {tuple(shape)}, got {arr.dtype} {arr.shape}"
        )
    return arr
