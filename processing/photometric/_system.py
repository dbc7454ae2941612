"""Batched per-pixel 3×3 normal equations of the Lambertian model I = s·b.

``s`` is a light vector (direction × intensity × falloff) and ``b = ρ n`` the
scaled normal. A light matrix ``S`` is either shared, (L, 3) for distant
lamps, or per pixel, (L, n, 3) for near lamps. Observations are (L, n) grey
or (L, n, C) colour, weights (L, n). Everything here is closed form, so a
million pixels solve without a Python loop or a LAPACK call each; the sums
over the lights keep the dtype they are given (float64, or float32 for the
IRLS reweighting steps), the 3×3 solves and conditions take float64.
"""

from __future__ import annotations

import numpy as np

from ._result import CONDITION_CAP

# Upper-triangle index pairs of a symmetric 3×3 matrix, and where each of the
# nine entries finds its value among them.
_PAIRS = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))
FULL_FROM_PAIRS = np.array([0, 1, 2, 1, 3, 4, 2, 4, 5])


def normal_matrix(lights: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """Σ_l w s sᵀ per pixel: (n, 3, 3), in the dtype of ``lights`` and ``weights``."""
    if lights.ndim == 2:
        outer = np.stack([lights[:, i] * lights[:, j] for i, j in _PAIRS])
        # (6, n) first: einsum writing pixel-major rows is ~10× slower.
        upper = np.einsum("kl,ln->kn", outer, weights).T
    else:
        weighted = lights * weights[..., None]
        upper = np.stack(
            [np.einsum("ln,ln->n", weighted[..., i], lights[..., j]) for i, j in _PAIRS], axis=1
        )
    return upper[:, FULL_FROM_PAIRS].reshape(-1, 3, 3)


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


def predict(lights: np.ndarray, scaled_normals: np.ndarray) -> np.ndarray:
    """s·b for every light and pixel: (L, n) from b (n, 3)."""
    if lights.ndim == 2:
        return np.einsum("li,in->ln", lights, np.ascontiguousarray(scaled_normals.T))
    return np.einsum("lni,ni->ln", lights, scaled_normals)


def eigvals_sym3(a: np.ndarray) -> np.ndarray:
    """Eigenvalues of symmetric 3×3 matrices, ascending: (n, 3) from (n, 3, 3).

    Closed-form trigonometric solution of the characteristic cubic (Smith,
    CACM 4(4), 1961); absolute accuracy ~ machine epsilon × largest eigenvalue.
    """
    q = np.trace(a, axis1=1, axis2=2) / 3.0
    off = a[:, 0, 1] ** 2 + a[:, 0, 2] ** 2 + a[:, 1, 2] ** 2
    diag = (a[:, 0, 0] - q) ** 2 + (a[:, 1, 1] - q) ** 2 + (a[:, 2, 2] - q) ** 2
    p = np.sqrt((diag + 2.0 * off) / 6.0)
    round_ = p <= np.finfo(np.float64).tiny  # a multiple of the identity
    safe_p = np.where(round_, 1.0, p)
    shifted = (a - q[:, None, None] * np.eye(3)) / safe_p[:, None, None]
    r = np.clip(_det3(shifted) / 2.0, -1.0, 1.0)
    phi = np.arccos(r) / 3.0
    largest = q + 2.0 * p * np.cos(phi)
    smallest = q + 2.0 * p * np.cos(phi + 2.0 * np.pi / 3.0)
    middle = 3.0 * q - largest - smallest
    out = np.stack([smallest, middle, largest], axis=1)
    out[round_] = q[round_, None]
    return out


def condition(a: np.ndarray) -> np.ndarray:
    """Condition number of the light matrix behind each normal matrix ``a``.

    ``a = Sᵀ W S``, so this is sqrt(λmax / λmin) of ``a``; ``CONDITION_CAP``
    where ``a`` is singular or zero. Returns (n,) float64.
    """
    ev = eigvals_sym3(a)
    hi, lo = ev[:, 2], ev[:, 0]
    ok = (hi > 0) & (lo > hi / CONDITION_CAP**2)
    ratio = np.divide(hi, lo, out=np.full_like(hi, CONDITION_CAP**2), where=ok)
    return np.sqrt(ratio)


def _det3(m: np.ndarray) -> np.ndarray:
    return (
        m[:, 0, 0] * (m[:, 1, 1] * m[:, 2, 2] - m[:, 1, 2] * m[:, 2, 1])
        - m[:, 0, 1] * (m[:, 1, 0] * m[:, 2, 2] - m[:, 1, 2] * m[:, 2, 0])
        + m[:, 0, 2] * (m[:, 1, 0] * m[:, 2, 1] - m[:, 1, 1] * m[:, 2, 0])
    )


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
