"""Batched per-pixel 3×3 normal equations of the Lambertian model I = s·b.

``s`` is a light vector (direction × intensity × falloff) and ``b = ρ n`` the
scaled normal. A light matrix ``S`` is either shared, (L, 3) for distant
lamps, or per pixel, (L, n, 3) for near lamps. Observations are (L, n) grey
or (L, n, C) colour, weights (L, n). The moments and the adjugate solves of
the numpy fit (``_block._fit``, unit weights and one light matrix); the
weighted sums, conditions and fits are compiled (:mod:`._kernels`,
:mod:`._near_kernel`).
"""

from __future__ import annotations

import numpy as np


def moment(lights: np.ndarray, weights: np.ndarray | None, obs: np.ndarray) -> np.ndarray:
    """Σ_l w I s per pixel: (n, 3) for grey obs, (n, 3, C) for colour (None: w = 1)."""
    wobs = obs if weights is None else obs * (weights[..., None] if obs.ndim == 3 else weights)
    if lights.ndim == 2:
        if obs.ndim == 2:
            return np.einsum("il,ln->ni", np.ascontiguousarray(lights.T), wobs)
        return np.einsum("il,lnc->nic", np.ascontiguousarray(lights.T), wobs)
    if obs.ndim == 2:
        return np.einsum("lni,ln->ni", lights, wobs)
    return np.einsum("lni,lnc->nic", lights, wobs)


def solve_sym3(a: np.ndarray, rhs: np.ndarray, solvable: np.ndarray) -> np.ndarray:
    """x with a x = rhs by the adjugate, where ``solvable``; 0 elsewhere.

    a : (n, 3, 3) symmetric; rhs : (n, 3) or (n, 3, C); solvable : (n,) bool,
    which the caller sets only for well-conditioned systems (so det ≠ 0).
    """
    c00 = a[:, 1, 1] * a[:, 2, 2] - a[:, 1, 2] ** 2
    c01 = a[:, 0, 2] * a[:, 1, 2] - a[:, 0, 1] * a[:, 2, 2]
    c02 = a[:, 0, 1] * a[:, 1, 2] - a[:, 0, 2] * a[:, 1, 1]
    c11 = a[:, 0, 0] * a[:, 2, 2] - a[:, 0, 2] ** 2
    c12 = a[:, 0, 1] * a[:, 0, 2] - a[:, 0, 0] * a[:, 1, 2]
    c22 = a[:, 0, 0] * a[:, 1, 1] - a[:, 0, 1] ** 2
    det = a[:, 0, 0] * c00 + a[:, 0, 1] * c01 + a[:, 0, 2] * c02
    inv_det = np.divide(1.0, det, out=np.zeros_like(det), where=solvable & (det != 0))
    adj = np.stack([c00, c01, c02, c01, c11, c12, c02, c12, c22], axis=1).reshape(-1, 3, 3)
    inv = adj * inv_det[:, None, None]
    if rhs.ndim == 2:
        return np.einsum("nij,nj->ni", inv, rhs)
    return np.einsum("nij,njc->nic", inv, rhs)
