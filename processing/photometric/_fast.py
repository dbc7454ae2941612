"""The unweighted route for distant lamps: one product with the pseudo-inverse.

A pixel lit by distant lamps whose observations are all usable solves as
``x = S⁺ I`` with the shared pseudo-inverse ``S⁺ = (SᵀS)⁻¹Sᵀ``: one pass over
its observations (compiled, :mod:`._kernels`), in the images' own precision
(float32 for float32 and integer images, float64 for float64 ones, or when
the light matrix is conditioned badly enough that float32 would lose
digits), counting clipped and lit observations on the way. The residual is
taken from ``I − S x`` directly in a second pass over the same pixels (in
cache), not from the normal-equation sums, so it keeps its digits in float32.

Pixels this route cannot answer — an observation at or above its clipping
level, a non-finite value, a sum that overflows, or a colour pixel dark in
some channels but not all — are returned as ``hard``
for the per-pixel route of :mod:`._block`, which rejects observations,
reports bad values and solves in float64. Both routes give the same outputs
and reasons (tests compare them).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._inputs import Stack
from ._kernels import pinv_moments, pinv_normals, pinv_store, residual_squares
from ._result import CONDITION_CAP

#: Above this condition number of the light matrix the route computes in float64.
FLOAT32_MAX_CONDITION = 1.0e3


@dataclass(frozen=True)
class PinvRoute:
    """Everything the route needs that is shared by all pixels of one solve."""

    lights: np.ndarray  # (L, 3), work dtype
    pinv_gain: np.ndarray  # (C, 3, L), work dtype: S⁺ with each column times the gain
    gain: np.ndarray  # (C, L), work dtype: stored value → normalised intensity
    clip_raw: np.ndarray  # (C, L), work dtype: stored value at or above which it is clipped
    dark_raw: float  # work dtype: stored value at or below which an observation is dark
    condition: float  # of the light matrix, capped

    @classmethod
    def prepare(cls, light_matrix: np.ndarray, condition: float, stack: Stack, dark_level):
        float32 = stack.values.dtype != np.float64 and condition <= FLOAT32_MAX_CONDITION
        dtype = np.float32 if float32 else np.float64
        pinv = np.linalg.pinv(light_matrix)
        return cls(
            lights=light_matrix.astype(dtype),
            pinv_gain=(pinv[None] * stack.gain.T[:, None, :]).astype(dtype),
            gain=np.ascontiguousarray(stack.gain.T, dtype=dtype),
            clip_raw=_level(np.ascontiguousarray(stack.clip_raw.T), dtype, np.inf),
            dark_raw=dtype(_level(dark_level / stack.scale, dtype, -np.inf)),
            condition=min(condition, CONDITION_CAP),
        )

    def solve(self, values: np.ndarray, start: int, count: int, pixel, out) -> np.ndarray:
        """Solve ``count`` pixels from ``start`` on and write them into ``out``.

        Parameters
        ----------
        values : (L, N) or (L, N, 3) C-contiguous stored values (any accepted dtype)
            The whole flattened stack, or a packed chunk of it.
        pixel : (count,) int64
            Where each pixel goes in ``out``.
        out : tuple of arrays
            The result's flat maps: normals (N, 3), albedo (N, C), reason,
            condition, residual, lights_used.

        Returns
        -------
        hard : (count,) bool
            Pixels to solve again on the per-pixel route (their entries in
            ``out`` are meaningless until it does).
        """
        n_lights = values.shape[0]
        work = self.pinv_gain.dtype
        if values.ndim == 2:
            planes = [(values, start)]
        else:  # one contiguous (L, count) image stack per channel
            planes = [
                (np.ascontiguousarray(values[:, start : start + count, c]), 0) for c in range(3)
            ]
        n_channels = len(planes)
        moments = np.empty((n_channels, 3, count), work)
        clipped = np.zeros(count, work)
        lit = np.empty((n_channels, count), work)
        n_clipped = np.empty(count, work)
        for c, (plane, offset) in enumerate(planes):
            pinv_moments(
                plane, offset, count, self.pinv_gain[c], self.clip_raw[c], self.dark_raw,
                moments[c], n_clipped, lit[c],
            )  # fmt: skip
            clipped += n_clipped
        normals = np.empty((3, count), work)
        albedo = np.empty((n_channels, count), work)
        fit = np.empty((n_channels, 3, count), work)
        pinv_normals(moments, normals, albedo, fit)
        sq = np.zeros(count, work)
        part = np.empty(count, work)
        for c, (plane, offset) in enumerate(planes):
            residual_squares(plane, offset, count, self.gain[c], self.lights, fit[c], part)
            sq += part
        hard = np.empty(count, np.bool_)
        pinv_store(
            normals, albedo, sq, clipped, lit, pixel, n_lights, self.condition, out, hard
        )  # fmt: skip
        return hard


def _level(level, dtype, towards: float):
    """A float64 level in ``dtype`` without changing any comparison with a stored value.

    The kernels compare in the work dtype (a float64 comparison would halve
    their SIMD width). Rounding the level towards +inf keeps ``v >= level``
    and towards −inf keeps ``v > level`` exact for every value of that dtype
    (the images' integers and float32 values are all exact in it).
    """
    near = np.asarray(level).astype(dtype)
    off = (near < level) if towards > 0 else (near > level)
    return np.where(off, np.nextafter(near, dtype(towards)), near).astype(dtype)
