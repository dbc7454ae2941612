"""Fit the glTF PBR model to a BTF's measured samples, texel by texel.

Levenberg–Marquardt on all texels at once (numpy, batched normal equations), with a
forward-difference Jacobian, box bounds by projection, a Cauchy robust loss in linear
radiance (iteratively reweighted: a highlight the model cannot follow, a speck of dust
or a shadow counts less), weak priors that hold a parameter the samples do not
determine where it started (roughness with no specular signal stays at its prior, not
at a bound), and two starts (smooth and glossy) of which each texel keeps the better.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, replace

import numpy as np

from processing.pbr._errors import PbrError
from rig.material import PbrFlag, PbrParams, evaluate_terms
from rig.material import evaluate_pbr as evaluate

__all__ = ["FitOptions", "PbrFitResult", "fit_texels"]

_H = 1e-5  # forward-difference step (parameters are O(1))


@dataclass(frozen=True)
class FitOptions:
    """Knobs of :func:`fit_texels`.

    iterations : LM iterations per start
    roughness_prior, sheen_roughness_prior : where an undetermined roughness stays
    prior_weight : strength of the priors, relative to the texel's mean radiance
    dark_level : a texel whose brightest sample is below this (relative radiance) is DARK
    saturation : sample values at or above it are clipped and left out (None: no clipping)
    """

    iterations: int = 30
    roughness_prior: float = 0.5
    sheen_roughness_prior: float = 0.5
    prior_weight: float = 0.03
    dark_level: float = 1e-3
    saturation: float | None = None


@dataclass(frozen=True)
class PbrFitResult:
    """Fitted parameters (leading shape (T,)), per-texel RMSE over the samples used
    (linear radiance, float32) and :class:`rig.material.PbrFlag` bits (uint8)."""

    params: PbrParams
    error_rmse: np.ndarray
    flags: np.ndarray


def fit_texels(
    samples, light, view, *, normal_init=None, sample_valid=None, options: FitOptions = FitOptions()
) -> PbrFitResult:
    """Fit :func:`processing.pbr.evaluate` to each texel's samples.

    Parameters
    ----------
    samples : (T, M, C) linear relative radiance, M measured (light, view) pairs
    light, view : (M, 3) unit vectors of the pairs, sample frame
    normal_init : (T, 3) unit normals to start from (PS maps); default the flat (0, 0, 1)
    sample_valid : (M,) bool, pairs to use (a view slot stored empty: False); default all
    options : FitOptions

    Returns
    -------
    PbrFitResult
        Finite everywhere. A texel with no usable sample keeps the priors and is flagged.
    """
    data = np.asarray(samples, np.float64)
    light, view = np.asarray(light, np.float64), np.asarray(view, np.float64)
    if data.ndim != 3 or data.shape[2] not in (1, 3):
        raise PbrError(f"samples: shape {data.shape}; expected (texels, pairs, 1 or 3 channels)")
    n_texels, n_pairs, channels = data.shape
    for name, table in (("light", light), ("view", view)):
        if table.shape != (n_pairs, 3) or not np.all(np.isfinite(table)):
            raise PbrError(
                f"{name}: shape {table.shape}; expected ({n_pairs}, 3) finite unit vectors"
            )
    use = np.ones(n_pairs, bool) if sample_valid is None else np.asarray(sample_valid, bool)
    if use.shape != (n_pairs,):
        raise PbrError(f"sample_valid: shape {use.shape}; expected ({n_pairs},) bool")
    if normal_init is not None and np.shape(normal_init) != (n_texels, 3):
        raise PbrError(f"normal_init: shape {np.shape(normal_init)}; expected ({n_texels}, 3)")
    weight = np.broadcast_to(use[None, :, None], data.shape).astype(np.float64)
    weight[~np.isfinite(data)] = 0.0  # a NaN or inf sample is left out, never fitted
    data = np.where(np.isfinite(data), data, 0.0)
    flags = np.zeros(n_texels, np.uint8)
    if options.saturation is not None:
        clipped = data >= options.saturation
        weight = np.where(clipped, 0.0, weight)
        flags[np.any(clipped & (weight == 0) & use[None, :, None], axis=(1, 2))] |= np.uint8(
            PbrFlag.SATURATED
        )
    peak = np.max(data * weight, axis=(1, 2))
    dark = peak < options.dark_level
    flags[dark] |= np.uint8(PbrFlag.DARK)
    sampling = _sampling_flags(light[use], view[use])
    flags |= sampling
    layout = _Layout(channels)
    if normal_init is None:
        normal_init = np.tile([0.0, 0.0, 1.0], (n_texels, 1))
    start = layout.start(data, weight, light, np.asarray(normal_init, np.float64), options)
    frozen = np.zeros(layout.size, bool)
    if sampling & PbrFlag.NORMAL_UNFIT:
        frozen[layout.normal] = True  # the lights cannot tell a tilt from the colour
    scale = np.maximum(np.sum(data * weight, axis=(1, 2)) / np.maximum(weight.sum((1, 2)), 1), 1e-3)
    best, best_cost = None, None
    for roughness in (0.25, 0.65):
        theta = start.copy()
        theta[:, layout.roughness] = roughness
        theta, cost = _levenberg_marquardt(
            theta, data, weight, light, view, layout, scale, options, frozen, active=~dark
        )
        if best is None:
            best, best_cost = theta, cost
        else:
            better = cost < best_cost
            best[better], best_cost[better] = theta[better], cost[better]
    best[dark] = start[dark]
    best[np.ix_(dark, np.r_[layout.base, layout.specular, layout.sheen])] = 0.0
    params = layout.params(best)
    fitted = evaluate(params, light, view)
    used = np.maximum(weight.sum((1, 2)), 1.0)
    error = np.sqrt(np.sum(weight * (fitted - data) ** 2, axis=(1, 2)) / used)
    matte = replace(params, specular=np.zeros_like(params.specular))
    specular_part = fitted - evaluate(matte, light, view)
    no_specular = np.max(np.abs(specular_part), axis=(1, 2)) < 0.01 * np.maximum(peak, 1e-12)
    flags[no_specular & ~dark] |= np.uint8(PbrFlag.NO_SPECULAR)
    return PbrFitResult(params.map(lambda a: a.astype(np.float32)), error.astype(np.float32), flags)


class _Layout:
    """Where each parameter sits in the per-texel vector θ, its bounds and priors."""

    def __init__(self, channels: int) -> None:
        c = channels
        self.base = slice(0, c)
        self.roughness = c
        self.specular = c + 1
        self.specular_colour = c + 2
        self.sheen = slice(c + 3, 2 * c + 3)
        self.sheen_roughness = 2 * c + 3
        self.anisotropy = slice(2 * c + 4, 2 * c + 6)  # (a_x, a_y) = s (cos 2φ, sin 2φ)
        self.normal = slice(2 * c + 6, 2 * c + 8)  # slopes: n ∝ (g_x, g_y, 1)
        self.size = 2 * c + 8
        self.lower = np.zeros(self.size)
        self.upper = np.ones(self.size)
        self.lower[self.roughness] = self.lower[self.sheen_roughness] = 0.03
        self.upper[self.specular_colour] = 25.0  # f0 up to 1
        self.lower[self.anisotropy], self.lower[self.normal] = -1.0, -3.0
        self.upper[self.normal] = 3.0

    def params(self, theta: np.ndarray) -> PbrParams:
        a = theta[:, self.anisotropy]
        g = theta[:, self.normal]
        normal = np.concatenate([g, np.ones_like(g[:, :1])], axis=1)
        return PbrParams(
            base_colour=theta[:, self.base],
            roughness=theta[:, self.roughness],
            specular=theta[:, self.specular],
            specular_colour=theta[:, self.specular_colour],
            sheen_colour=theta[:, self.sheen],
            sheen_roughness=theta[:, self.sheen_roughness],
            anisotropy=np.minimum(np.hypot(a[:, 0], a[:, 1]), 1.0),
            anisotropy_deg=np.rad2deg(0.5 * np.arctan2(a[:, 1], a[:, 0])) % 180.0,
            normal=normal / np.linalg.norm(normal, axis=1, keepdims=True),
        )

    def start(self, data, weight, light, normal, options: FitOptions) -> np.ndarray:
        """θ to start from: the normal given, base colour from the darker half of the samples
        (a diffuse estimate, away from highlights), some specular and a little sheen."""
        theta = np.zeros((len(data), self.size))
        cos = np.clip(light @ normal.T, 0.0, None).T  # (T, M)
        ratio = np.where(
            (cos > 0.2)[..., None] & (weight > 0), data / np.maximum(cos, 0.2)[..., None], np.nan
        )
        with warnings.catch_warnings():  # a texel without a usable sample: NaN, then 0
            warnings.simplefilter("ignore", RuntimeWarning)
            diffuse = np.nanpercentile(ratio, 40, axis=1)
        theta[:, self.base] = np.clip(np.nan_to_num(diffuse, nan=0.0), 0.0, 1.0)
        theta[:, self.roughness] = options.roughness_prior
        theta[:, self.specular] = 0.5
        theta[:, self.specular_colour] = 1.0
        theta[:, self.sheen] = 0.02
        theta[:, self.sheen_roughness] = options.sheen_roughness_prior
        theta[:, self.anisotropy] = 0.05
        slopes = normal[:, :2] / np.maximum(normal[:, 2:], 0.25)
        theta[:, self.normal] = np.clip(slopes, -3.0, 3.0)
        return theta

    def priors(self, theta0: np.ndarray, options: FitOptions):
        """(index, target (T,)) pairs: what an undetermined parameter is pulled towards."""
        t = len(theta0)
        pairs = [
            (self.roughness, np.full(t, options.roughness_prior)),
            (self.sheen_roughness, np.full(t, options.sheen_roughness_prior)),
            (self.specular_colour, np.ones(t)),
        ]
        pairs += [(i, np.zeros(t)) for i in range(self.size)[self.anisotropy]]
        pairs += [(i, np.zeros(t)) for i in range(self.size)[self.sheen]]
        pairs += [(i, theta0[:, i].copy()) for i in range(self.size)[self.normal]]
        return pairs


def _levenberg_marquardt(
    theta, data, weight, light, view, layout, scale, options, frozen, *, active
):
    """Minimise Σ ρ(model − data) + priors over the ``active`` texels; θ and each texel's
    final cost. A texel leaves the iteration once its steps stop paying."""
    n_texels = len(theta)
    targets = layout.priors(theta, options)
    prior_index = np.array([i for i, _ in targets])
    prior_target = np.stack([target for _, target in targets], 1)  # (T, Q)
    prior_scale = options.prior_weight * scale  # (T,)
    plain = weight.reshape(n_texels, -1)
    robust = plain.copy()
    damping = np.full(n_texels, 1e-2)
    free = np.flatnonzero(~frozen)
    prior_jacobian = (prior_index[:, None] == free[None, :]).astype(np.float64)  # (Q, P)
    base_of = {p: c for c, p in enumerate(range(layout.size)[layout.base])}
    sheen_of = {p: c for c, p in enumerate(range(layout.size)[layout.sheen])}

    def residuals(th, idx):
        diffuse, specular, sheen = evaluate_terms(layout.params(th), light, view)
        model = (diffuse[..., None] * th[:, None, layout.base] + specular[..., None]
                 + sheen[..., None] * th[:, None, layout.sheen])  # fmt: skip
        data_rows = (model - data[idx]).reshape(len(idx), -1)
        prior_rows = prior_scale[idx, None] * (th[:, prior_index] - prior_target[idx])
        return data_rows, prior_rows, diffuse, sheen

    def cost_of(data_rows, prior_rows, w):
        return np.sum(w * data_rows**2, 1) + np.sum(prior_rows**2, 1)

    live = np.flatnonzero(active)
    for iteration in range(options.iterations):
        if live.size == 0:
            break
        th = theta[live]
        data_rows, prior_rows, diffuse, sheen = residuals(th, live)
        if iteration % 5 == 0:
            robust[live] = plain[live] * _cauchy(data_rows, plain[live], scale[live])
        w = robust[live]
        cost = cost_of(data_rows, prior_rows, w)
        jacobian = np.zeros((len(live), *data.shape[1:], len(free)))
        for k, p in enumerate(free):
            if p in base_of:  # the colours enter linearly: their columns are the terms
                jacobian[:, :, base_of[p], k] = diffuse
            elif p in sheen_of:  # (leaving out the albedo scaling's dependence on them)
                jacobian[:, :, sheen_of[p], k] = sheen
            else:
                step = np.where(th[:, p] + _H <= layout.upper[p], _H, -_H)
                shifted = th.copy()
                shifted[:, p] += step
                moved = residuals(shifted, live)[0]
                jacobian[..., k] = ((moved - data_rows) / step[:, None]).reshape(
                    jacobian.shape[:-1]
                )
        jacobian = jacobian.reshape(len(live), -1, len(free))
        wj = w[..., None] * jacobian
        jp = prior_scale[live, None, None] * prior_jacobian[None]
        normal_matrix = np.einsum("tkp,tkq->tpq", wj, jacobian)
        normal_matrix += np.einsum("tkp,tkq->tpq", jp, jp)
        gradient = np.einsum("tkp,tk->tp", wj, data_rows) + np.einsum("tkp,tk->tp", jp, prior_rows)
        diagonal = np.einsum("tpp->tp", normal_matrix)
        damped = normal_matrix + (damping[live, None] * (diagonal + 1e-9))[..., None] * np.eye(
            len(free)
        )
        delta = -np.linalg.solve(damped, gradient[..., None])[..., 0]
        trial = th.copy()
        trial[:, free] = np.clip(th[:, free] + delta, layout.lower[free], layout.upper[free])
        trial_cost = cost_of(*residuals(trial, live)[:2], w)
        better = trial_cost < cost
        theta[live[better]] = trial[better]
        damping[live] = np.clip(
            np.where(better, damping[live] * 0.3, damping[live] * 10.0), 1e-7, 1e7
        )
        gain = (cost - trial_cost) / np.maximum(cost, 1e-300)
        done = (better & (gain < 1e-7)) | (damping[live] >= 1e7)
        live = live[~done]
    final = np.zeros(n_texels)
    data_rows, prior_rows, *_ = residuals(theta, np.arange(n_texels))
    final[active] = cost_of(data_rows, prior_rows, plain)[active]
    return theta, final


def _cauchy(residual, weight, scale):
    """Cauchy weights 1 / (1 + (r/σ)²), σ from the texel's median absolute residual
    (at least 2 % of its mean radiance, so an exact fit does not reject everything)."""
    used = weight.reshape(len(residual), -1) > 0
    magnitude = np.where(used, np.abs(residual), np.nan)
    with warnings.catch_warnings():  # a texel without a usable sample: NaN, then 0
        warnings.simplefilter("ignore", RuntimeWarning)
        mad = np.nan_to_num(np.nanmedian(magnitude, axis=1), nan=0.0)
    sigma = np.maximum(3.0 * 1.4826 * mad, 0.02 * scale)
    return 1.0 / (1.0 + (residual / sigma[:, None]) ** 2)


def _sampling_flags(light: np.ndarray, view: np.ndarray) -> np.uint8:
    """Flags every texel shares: how well the measured directions pin the model down."""
    flags = 0
    distinct = np.unique(np.round(light, 6), axis=0)
    if len(distinct) == 1:
        flags |= PbrFlag.SINGLE_LIGHT
    if len(distinct) < 3 or np.linalg.matrix_rank(distinct, tol=1e-3) < 3:
        flags |= PbrFlag.NORMAL_UNFIT
    if len(distinct) > 1 and np.ptp(distinct[:, 2]) < 1e-3:
        flags |= PbrFlag.ONE_ELEVATION
    return np.uint8(flags)
