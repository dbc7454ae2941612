"""Light models (distant and near lamps) and the pixel grid they shine on.

Conventions: the sample frame has z along the sample normal; light directions
point from the surface towards the lamp. Image rows run along -y and columns
along +x (row 0 at +y), as :func:`rig.geometry.texel_centers_mm` lays out
normtextures.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ._errors import PhotometricError
from ._near_kernel import near_light_planes

_UNIT_TOLERANCE = 1e-3


def _finite_array(value, name: str, shape_text: str, ndim: int, last: int | None) -> np.ndarray:
    try:
        arr = np.array(value, dtype=np.float64)
    except (TypeError, ValueError) as err:
        raise PhotometricError(f"{name}: expected {shape_text} numbers, got {value!r}") from err
    if arr.ndim != ndim or (last is not None and arr.shape[-1] != last):
        raise PhotometricError(f"{name}: expected shape {shape_text}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        bad = np.argwhere(~np.isfinite(arr))[0].tolist()
        raise PhotometricError(f"{name}: entry {bad} is not finite; all values must be finite")
    arr.setflags(write=False)
    return arr


def _intensities(value, n_lights: int) -> np.ndarray:
    if value is None:
        arr = np.ones(n_lights)
        arr.setflags(write=False)
        return arr
    try:
        arr = np.array(value, dtype=np.float64)
    except (TypeError, ValueError) as err:
        raise PhotometricError(f"intensities: expected numbers, got {value!r}") from err
    if arr.shape not in ((n_lights,), (n_lights, 3)):
        raise PhotometricError(
            f"intensities: expected one per light, ({n_lights},), or one per light and "
            f"colour channel, ({n_lights}, 3); got shape {arr.shape}"
        )
    bad = ~np.isfinite(arr) | (arr <= 0)
    if np.any(bad):
        i = tuple(int(k) for k in np.argwhere(bad)[0])
        index = i[0] if arr.ndim == 1 else i
        raise PhotometricError(
            f"intensities[{index}] = {arr[i]:g}; lamp intensities must be finite and > 0"
        )
    arr.setflags(write=False)
    return arr


def _brightness(intensities: np.ndarray) -> np.ndarray:
    """(L,) lamp brightness: the intensity, or its mean over the colour channels."""
    return intensities if intensities.ndim == 1 else intensities.mean(axis=1)


def _colour_balance(intensities: np.ndarray) -> np.ndarray | None:
    """(L, 3) each channel's intensity over the lamp's brightness; None for grey intensities."""
    if intensities.ndim == 1:
        return None
    return intensities / intensities.mean(axis=1, keepdims=True)


def _check_count(n_lights: int, name: str) -> None:
    if n_lights < 3:
        raise PhotometricError(
            f"{name}: photometric stereo needs at least 3 lights, got {n_lights}"
        )


@dataclass(frozen=True)
class DistantLights:
    """Lamps far enough away that one direction serves every pixel.

    Parameters
    ----------
    directions : (L, 3) array_like
        Unit vectors in the sample frame pointing towards each lamp, z ≥ 0.
    intensities : (L,) or (L, 3) array_like, optional
        Irradiance each lamp delivers to a surface facing it (default 1),
        per colour channel when (L, 3) (a real lamp is rarely white). The
        lamp's brightness (the mean over channels) scales its light vector;
        its colour balance (channel ÷ brightness) divides the observations
        of colour images, so albedo is per unit intensity in every channel.
    """

    directions: np.ndarray
    intensities: np.ndarray | None = field(default=None)

    def __post_init__(self):
        dirs = _finite_array(self.directions, "directions", "(L, 3)", 2, 3)
        _check_count(len(dirs), "directions")
        norms = np.linalg.norm(dirs, axis=1)
        off = np.abs(norms - 1.0) > _UNIT_TOLERANCE
        if np.any(off):
            i = int(np.argmax(off))
            raise PhotometricError(
                f"directions[{i}] has length {norms[i]:.6g}; light directions must be unit "
                f"vectors (within {_UNIT_TOLERANCE}); normalise them first"
            )
        below = dirs[:, 2] < 0
        if np.any(below):
            i = int(np.argmax(below))
            raise PhotometricError(
                f"directions[{i}] has z = {dirs[i, 2]:.4g} < 0: a lamp below the sample plane "
                "cannot light it; directions point from the surface towards the lamp (z ≥ 0)"
            )
        unit = dirs / norms[:, None]
        unit.setflags(write=False)
        object.__setattr__(self, "directions", unit)
        object.__setattr__(self, "intensities", _intensities(self.intensities, len(dirs)))

    @property
    def n_lights(self) -> int:
        return len(self.directions)

    def light_matrix(self) -> np.ndarray:
        """(L, 3) float64: direction times brightness, one row per lamp."""
        return self.directions * _brightness(self.intensities)[:, None]

    def colour_balance(self) -> np.ndarray | None:
        """(L, 3) per-channel intensity ÷ brightness, or None for (L,) intensities."""
        return _colour_balance(self.intensities)


@dataclass(frozen=True)
class NearLights:
    """Point lamps at known positions: per-pixel direction and 1/r² falloff.

    Parameters
    ----------
    positions_mm : (L, 3) array_like
        Lamp positions in the sample frame, in mm, above the sample (z > 0).
    intensities : (L,) or (L, 3) array_like, optional
        Irradiance each lamp delivers at the sample-frame origin to a surface
        facing it (default 1), per colour channel when (L, 3) (as for
        :class:`DistantLights`). A pixel at distance r from lamp l receives
        ``intensities[l] · (r0_l / r)²`` with ``r0_l = |positions_mm[l]|``,
        so the albedo means the same as with :class:`DistantLights`.
    """

    positions_mm: np.ndarray
    intensities: np.ndarray | None = field(default=None)

    def __post_init__(self):
        pos = _finite_array(self.positions_mm, "positions_mm", "(L, 3)", 2, 3)
        _check_count(len(pos), "positions_mm")
        low = pos[:, 2] <= 0
        if np.any(low):
            i = int(np.argmax(low))
            raise PhotometricError(
                f"positions_mm[{i}] has z = {pos[i, 2]:.4g} mm; lamps must be above the "
                "sample plane (z > 0 mm)"
            )
        object.__setattr__(self, "positions_mm", pos)
        object.__setattr__(self, "intensities", _intensities(self.intensities, len(pos)))

    @property
    def n_lights(self) -> int:
        return len(self.positions_mm)

    def light_vectors(self, points_mm: np.ndarray) -> np.ndarray:
        """Per-point light vectors: unit direction × brightness × falloff.

        Parameters
        ----------
        points_mm : (N, 3) float64
            Surface points in the sample frame, mm.

        Returns
        -------
        (L, N, 3) float64
            A view of x, y, z planes (3, L, N), the layout the compiled
            per-pixel route reads.
        """
        r0_sq = np.einsum("li,li->l", self.positions_mm, self.positions_mm)
        points = np.ascontiguousarray(np.asarray(points_mm, np.float64).T)
        planes = np.empty((3, self.n_lights, points.shape[1]))
        near_light_planes(self.positions_mm, _brightness(self.intensities) * r0_sq, points, planes)
        return np.moveaxis(planes, 0, 2)

    def colour_balance(self) -> np.ndarray | None:
        """(L, 3) per-channel intensity ÷ brightness, or None for (L,) intensities."""
        return _colour_balance(self.intensities)


@dataclass(frozen=True)
class PixelGrid:
    """A regular grid of pixels on the sample plane (row 0 at +y, column 0 at -x).

    Parameters
    ----------
    shape : (H, W)
        Image size in pixels.
    pitch_mm : float
        Pixel spacing on the sample, mm (same along x and y).
    centre_mm : (2,) float
        Sample-frame (x, y) of the grid centre, mm.
    """

    shape: tuple[int, int]
    pitch_mm: float
    centre_mm: tuple[float, float] = (0.0, 0.0)

    def __post_init__(self):
        if len(self.shape) != 2 or min(self.shape) < 1:
            raise PhotometricError(f"shape: expected (H, W) with H, W ≥ 1, got {self.shape}")
        if not (np.isfinite(self.pitch_mm) and self.pitch_mm > 0):
            raise PhotometricError(f"pitch_mm: expected a finite value > 0, got {self.pitch_mm}")
        object.__setattr__(self, "shape", (int(self.shape[0]), int(self.shape[1])))

    @classmethod
    def for_sample(cls, sample_mm: float, n: int) -> PixelGrid:
        """The n×n texel grid of :func:`rig.geometry.texel_centers_mm` over a sample square."""
        if n < 1 or not sample_mm > 0:
            raise PhotometricError(
                f"for_sample: need n ≥ 1 and sample_mm > 0, got {n}, {sample_mm}"
            )
        return cls((n, n), sample_mm / n)

    def positions_mm(self, height_mm: np.ndarray | None = None) -> np.ndarray:
        """(H, W, 3) float64 sample-frame positions of the pixel centres, mm.

        ``height_mm`` (H, W), when given, is the surface z of each pixel.
        """
        h, w = self.shape
        x = self.centre_mm[0] + (np.arange(w) - (w - 1) / 2) * self.pitch_mm
        y = self.centre_mm[1] - (np.arange(h) - (h - 1) / 2) * self.pitch_mm
        xy = np.stack(np.meshgrid(x, y), axis=-1)
        z = np.zeros((h, w)) if height_mm is None else np.asarray(height_mm, dtype=np.float64)
        if z.shape != (h, w):
            raise PhotometricError(f"height_mm: expected shape {(h, w)}, got {z.shape}")
        return np.concatenate([xy, z[..., None]], axis=-1)


def light_set_condition(light_matrix: np.ndarray) -> float:
    """Condition number of an (L, 3) light matrix (inf when rank-deficient).

    The ratio of its largest to smallest singular value: how much noise in the
    images is amplified into the scaled normal. Coplanar lights (all on one
    great circle, e.g. one azimuth plane) give rank 2 and an infinite value.
    """
    sv = np.linalg.svd(np.asarray(light_matrix, dtype=np.float64), compute_uv=False)
    if sv[-1] <= sv[0] * np.finfo(np.float64).eps * 8:
        return float("inf")
    return float(sv[0] / sv[-1])
