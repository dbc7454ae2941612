"""The unweighted route for distant lamps: one product with the pseudo-inverse.

A pixel lit by distant lamps whose observations are all usable solves as
``x = S⁺ I`` with the shared pseudo-inverse ``S⁺ = (SᵀS)⁻¹Sᵀ``: one pass over
its observations, in the images' own precision (float32 for float32 and
integer images, float64 for float64 ones, or when the light matrix is
conditioned badly enough that float32 would lose digits). The residual is
taken from ``I − S x`` directly, not from the normal-equation sums, so it
keeps its digits in float32.

Pixels this route cannot answer — an observation at or above the saturation
level, a non-finite value or a sum that overflows — are returned as ``hard``
for the per-pixel route of :mod:`._block`, which rejects observations,
reports bad values and solves in float64. Both routes give the same outputs
and reasons (tests compare them).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._inputs import Stack
from ._result import CONDITION_CAP, Reason

#: Above this condition number of the light matrix the route computes in float64.
FLOAT32_MAX_CONDITION = 1.0e3


@dataclass(frozen=True)
class PinvRoute:
    """Everything the route needs that is shared by all pixels of one solve."""

    lights: np.ndarray  # (L, 3), work dtype
    pinv: np.ndarray  # (3, L), work dtype
    condition: float  # of the light matrix, capped
    scale: float  # stored value → normalised intensity
    saturation_raw: float  # stored value at or above which an observation is clipped
    dark_level: float  # normalised

    @classmethod
    def prepare(cls, light_matrix: np.ndarray, condition: float, stack: Stack, dark_level):
        float32 = stack.values.dtype != np.float64 and condition <= FLOAT32_MAX_CONDITION
        dtype = np.float32 if float32 else np.float64
        return cls(
            lights=light_matrix.astype(dtype),
            pinv=np.linalg.pinv(light_matrix).astype(dtype),
            condition=min(condition, CONDITION_CAP),
            scale=stack.scale,
            saturation_raw=stack.saturation / stack.scale,
            dark_level=dark_level,
        )

    def solve(self, raw: np.ndarray) -> tuple[dict, np.ndarray]:
        """Solve pixels from their stored observations.

        Parameters
        ----------
        raw : (L, n) or (L, n, 3) stored values (any accepted dtype)

        Returns
        -------
        block : dict of per-pixel arrays named like ``PhotometricResult`` fields
        hard : (n,) bool
            Pixels to solve again on the per-pixel route (their block
            entries are meaningless).
        """
        n_lights, n = raw.shape[:2]
        colour = raw.ndim == 3
        peak = raw.max(axis=0)
        clipped = peak >= self.saturation_raw
        hard = clipped.any(axis=1) if colour else clipped
        work = raw.astype(self.pinv.dtype, copy=False)
        with np.errstate(over="ignore", invalid="ignore"):
            if colour:
                per_channel = np.einsum("il,lnc->inc", self.pinv, work)
                scaled = per_channel.mean(axis=2)
            else:
                # einsum, not BLAS: a threaded GEMM this skinny stalls when cores are shared.
                scaled = np.einsum("il,ln->in", self.pinv, work)
            rho = np.sqrt(np.einsum("in,in->n", scaled, scaled))
            positive = rho > 0
            normals = np.divide(scaled, rho, out=np.zeros_like(scaled), where=positive)
            if colour:
                albedo = np.einsum("inc,in->nc", per_channel, normals)
                shading = np.einsum("li,in->ln", self.lights, normals)
                misfit = work - shading[..., None] * albedo
                sq = np.einsum("lnc,lnc->n", misfit, misfit) / 3.0
            else:
                albedo = rho
                predicted = np.einsum("li,in->ln", self.lights, scaled)
                misfit = np.subtract(work, predicted, out=predicted)
                sq = np.einsum("ln,ln->n", misfit, misfit)
            residual = np.sqrt(sq / n_lights) * self.scale
        hard |= ~np.isfinite(residual)
        brightest = (peak.mean(axis=1) if colour else peak) * self.scale
        reason = np.select(
            [brightest <= self.dark_level, ~positive, normals[2] < 0],
            [Reason.DARK, Reason.DARK, Reason.BELOW_HORIZON],
            Reason.OK,
        ).astype(np.uint8)
        valid = reason == Reason.OK
        return {
            "normals": np.where(valid, normals, np.array([[0.0], [0.0], [1.0]])).T,
            "albedo": np.where(valid[:, None] if colour else valid, albedo * self.scale, 0.0),
            "reason": reason,
            "condition": np.full(n, self.condition),
            "residual": np.where(valid, residual, 0.0),
            "lights_used": np.full(n, n_lights, np.uint16),
        }, hard
