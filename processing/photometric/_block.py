"""Solve one chunk of pixels: weights, normal equations, classification, fill.

Every quantity of the fit follows from four per-pixel sums over the lights
used, so no per-observation residual pass is needed:
``A = Σ w s sᵀ``, ``g = Σ w I s``, ``e = Σ w I²`` and ``Σ w``; the residual of
``x = ρ n`` is ``e − 2 x·g + xᵀ A x``.
"""

from __future__ import annotations

import numpy as np

from . import _robust, _system
from ._kernels import conditions, fit_from_sums, sum_arrays, weighted_sums
from ._near_kernel import near_weighted_sums
from ._result import CONDITION_CAP, Reason


def solve_block(
    obs: np.ndarray,
    energy: np.ndarray,
    dark: np.ndarray,
    clipped: np.ndarray | None,
    lights: np.ndarray,
    shared_condition,
    options,
) -> dict:
    """Solve pixels of one chunk.

    Parameters
    ----------
    obs : (L, n) or (L, n, C) float64
        Normalised observations (divided by the lamps' colour balance).
    energy : (n,) or (n, C) float64
        Σ_l I² per pixel (and channel).
    dark : (n,) bool
        Whether the pixel's brightest observation as stored (mean over
        channels of each channel's maximum) is at or below the dark level.
    clipped : (L, n) bool or None
        Observations at or above their clipping level in any channel (None:
        none is).
    lights : (L, 3) or (L, n, 3) float64
        Light vectors (shared for distant lamps, per pixel for near ones).
    shared_condition : float or None
        Condition number of the shared light matrix (distant lamps).
    options : _solve._Options

    Returns
    -------
    dict of per-pixel arrays named like ``PhotometricResult`` fields.
    """
    n_lights, n = obs.shape[:2]
    colour = obs.ndim == 3
    grey = obs.mean(axis=2) if colour else obs
    n_unsaturated = n_lights - (clipped.sum(axis=0) if clipped is not None else 0)
    usable = ~clipped if clipped is not None else np.ones(grey.shape, bool)

    if lights.ndim == 3:
        condition_full, sums = _near_sums(obs, grey, usable, clipped is None, lights, options)
        used = sums[4].astype(np.int64)
        condition_used = _conditions(sums[0])
        normals, albedo, residual, positive = _fit_compiled(
            sums, condition_used, options.max_condition
        )
    else:
        condition_full = np.full(n, shared_condition)
        if shared_condition > options.max_condition:
            return _coplanar(n, colour, condition_full)
        condition_used, used, (normals, albedo, residual, positive) = _distant_fit(
            obs, energy, grey, usable, clipped is None, lights, shared_condition, options
        )

    reason = np.select(
        [
            condition_full > options.max_condition,
            dark,
            n_unsaturated < 3,
            used < 3,
            condition_used > options.max_condition,
            ~positive,
            normals[:, 2] < 0,
        ],
        [
            Reason.COPLANAR_LIGHTS,
            Reason.DARK,
            Reason.SATURATED,
            Reason.TOO_FEW_LIGHTS,
            Reason.ILL_CONDITIONED,
            Reason.DARK,
            Reason.BELOW_HORIZON,
        ],
        Reason.OK,
    ).astype(np.uint8)
    valid = reason == Reason.OK
    fill_normal = np.array([0.0, 0.0, 1.0])
    condition = np.where(reason == Reason.COPLANAR_LIGHTS, condition_full, condition_used)
    condition = np.where(used >= 3, condition, 0.0)
    return {
        "normals": np.where(valid[:, None], normals, fill_normal),
        "albedo": np.where(valid[:, None] if colour else valid, albedo, 0.0),
        "reason": reason,
        "condition": np.minimum(condition, CONDITION_CAP),
        "residual": np.where(valid, residual, 0.0),
        "lights_used": used.astype(np.uint16),
    }


def _distant_fit(
    obs, energy, grey, usable, all_usable: bool, lights, shared_condition, options
) -> tuple:
    """One light matrix (L, 3): condition and count of the lights used, and the fit."""
    n_lights, n = grey.shape
    if options.method == "irls":
        sums = _irls_sums(_planes(obs), grey, usable, lights, options)
    else:
        weights = _weights(grey, usable, lights, all_usable, options)
        if weights is None:  # every observation, unit weight
            condition_used = np.full(n, shared_condition)
            a = np.broadcast_to(lights.T @ lights, (n, 3, 3))
            g = _system.moment(lights, None, obs)
            used = np.full(n, n_lights)
            fit = _fit(a, g, energy, np.full(n, float(n_lights)), used, condition_used,
                       options.max_condition)  # fmt: skip
            return condition_used, used, fit
        planes = _planes(obs)
        sums = sum_arrays(n, planes.shape[0])
        weighted_sums(np.ascontiguousarray(weights), planes, lights, *sums)
    condition_used = _conditions(sums[0])
    fit = _fit_compiled(sums, condition_used, options.max_condition)
    return condition_used, sums[4].astype(np.int64), fit


def _near_sums(obs, grey, usable, all_usable: bool, lights, options) -> tuple:
    """Light vectors per pixel (L, n, 3): the conditions of all lights, and the fit's sums.

    Both compiled (:func:`._near_kernel.near_weighted_sums`); returns
    ``condition_full`` (n,) and the sums as :func:`._kernels.weighted_sums` gives them.
    """
    n_lights, n = grey.shape
    light_planes = np.ascontiguousarray(np.moveaxis(lights, 2, 0))
    planes = _planes(obs)
    unit = np.ones((n_lights, n), np.float32)
    if options.method == "irls":
        sums = _irls_sums(planes, grey, usable, light_planes, options)
    else:
        weights = _weights(grey, usable, lights, all_usable, options)
        sums = sum_arrays(n, planes.shape[0])
        near_weighted_sums(
            unit if weights is None else np.ascontiguousarray(weights), planes, light_planes, *sums
        )
        if weights is None:  # every observation, unit weight: the fit's own sums
            return _conditions(sums[0]), sums
    full = sum_arrays(n, 0)
    near_weighted_sums(unit, planes[:0], light_planes, *full)
    return _conditions(full[0]), sums


def _irls_sums(planes, grey, usable, lights, options) -> tuple:
    """The IRLS reweighting and the fit's sums in one compiled pass (:func:`._robust.irls_fit`)."""
    return _robust.irls_fit(
        planes,
        grey,
        usable,
        lights,
        shadow_fraction=options.shadow_fraction,
        highlight_fraction=options.highlight_fraction,
        iterations=options.irls_iterations,
        max_condition=options.max_condition,
    )[1]


def _weights(grey, usable, lights, all_usable: bool, options) -> np.ndarray | None:
    """Per-observation weights, or None when every observation has weight 1."""
    if options.method == "lsq":
        return None if all_usable else usable.astype(np.float64)
    if options.method == "threshold":
        return _robust.threshold_weights(
            grey,
            usable,
            shadow_fraction=options.shadow_fraction,
            highlight_fraction=options.highlight_fraction,
        )
    return _robust.irls_weights(
        grey,
        usable,
        lights,
        shadow_fraction=options.shadow_fraction,
        highlight_fraction=options.highlight_fraction,
        iterations=options.irls_iterations,
        max_condition=options.max_condition,
    )


def _fit(a, g, e, weight_sum, used, condition_used, max_condition) -> tuple:
    """Normals, albedo, residual and whether solved with ρ > 0, from the four sums.

    a (n, 3, 3), g (n, 3) or (n, 3, C), e (n,) or (n, C), weight_sum and used (n,).
    """
    n = a.shape[0]
    colour = g.ndim == 3
    solvable = (used >= 3) & (condition_used <= max_condition)
    g_grey = g.mean(axis=2) if colour else g
    scaled = _system.solve_sym3(a, g_grey, solvable)
    rho = np.sqrt(np.einsum("ni,ni->n", scaled, scaled))
    positive = solvable & (rho > 0)
    normals = np.divide(scaled, rho[:, None], out=np.zeros_like(scaled), where=positive[:, None])
    if colour:
        per_channel = _system.solve_sym3(a, g, solvable)
        albedo = np.einsum("nic,ni->nc", per_channel, normals)
        along_g = np.einsum("ni,nic->nc", normals, g)
    else:
        albedo = rho
        along_g = np.einsum("ni,ni->n", normals, g)
    n_a_n = np.einsum("ni,nij,nj->n", normals, a, normals)
    if colour:
        n_a_n = n_a_n[:, None]
    sq = np.clip(e - 2.0 * albedo * along_g + albedo**2 * n_a_n, 0.0, None)
    if colour:
        sq = sq.mean(axis=1)
    residual = np.sqrt(np.divide(sq, weight_sum, out=np.zeros(n), where=weight_sum > 0))
    return normals, albedo, residual, positive


def _fit_compiled(sums: tuple, condition_used: np.ndarray, max_condition: float) -> tuple:
    """:func:`_fit`, compiled, from the sums of :func:`weighted_sums` (a tuple of five)."""
    n, n_channels = sums[0].shape[1], sums[1].shape[0]
    normals = np.empty((n, 3))
    albedo = np.empty((n, n_channels))
    residual = np.empty(n)
    positive = np.empty(n, bool)
    fit_from_sums(*sums, condition_used, max_condition, normals, albedo, residual, positive)
    return normals, (albedo if n_channels > 1 else albedo[:, 0]), residual, positive


def _planes(obs: np.ndarray) -> np.ndarray:
    """The observations as (C, L, n) planes, C-contiguous (grey: a view)."""
    return np.ascontiguousarray(np.moveaxis(obs, 2, 0)) if obs.ndim == 3 else obs[None]


def _conditions(upper: np.ndarray) -> np.ndarray:
    """Conditions (:func:`._kernels.condition3`) of the compiled sums' normal matrices: (n,)."""
    out = np.empty(upper.shape[1])
    conditions(upper, out)
    return out


def _coplanar(n: int, colour: bool, condition_full: np.ndarray) -> dict:
    normals = np.zeros((n, 3))
    normals[:, 2] = 1.0
    return {
        "normals": normals,
        "albedo": np.zeros((n, 3) if colour else n),
        "reason": np.full(n, Reason.COPLANAR_LIGHTS, np.uint8),
        "condition": np.minimum(condition_full, CONDITION_CAP),
        "residual": np.zeros(n),
        "lights_used": np.zeros(n, np.uint16),
    }
