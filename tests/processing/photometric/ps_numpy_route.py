"""The per-pixel route as numpy took it: the reference the compiled kernels are held to.

Batched per-pixel 3×3 normal matrices and predictions as einsums, conditions
from closed-form batched eigenvalues (Smith, CACM 4(4), 1961), and the IRLS
reweighting step by step with a sort per pixel for the median. float32
reweighting, float64 3×3 systems, as the kernels take them. Nothing here comes
from the library but its public condition cap: the constants are the method's
as docs/photometric.md states them, and the sums and solves are plain numpy.
"""

import numpy as np

from processing.photometric import CONDITION_CAP

#: Tukey's biweight constant (95 % efficiency under Gaussian noise).
TUKEY_C = 4.685
#: MAD → standard deviation for Gaussian noise.
MAD_TO_SIGMA = 1.4826
#: The residual scale's floor, relative to the pixel's reference brightness.
SCALE_FLOOR = 1e-3

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


def irls_weights_stepwise(
    grey, usable, lights, *, shadow_fraction, highlight_fraction, iterations, max_condition
) -> np.ndarray:
    """IRLS weights (Tukey biweight on MAD-scaled residuals) with a light vector per pixel
    (L, n, 3), in numpy."""
    ref = reference_level(grey, highlight_fraction)
    support = usable & (grey >= shadow_fraction * ref)
    weights = (support & (grey <= ref)).astype(np.float32)
    floor = SCALE_FLOOR * np.maximum(ref, 0.0)
    grey32 = grey.astype(np.float32)
    lights32 = lights.astype(np.float32)
    shadow_level = (shadow_fraction * ref).astype(np.float32)
    for _ in range(iterations):
        a = normal_matrix(lights32, weights).astype(np.float64)
        ok = condition(a) <= max_condition
        g = moment(lights32, weights, grey32).astype(np.float64)
        b = solve(a, g, ok).astype(np.float32)
        predicted = predict(lights32, b)
        # |residual| in place: the biweight below needs only its square.
        residual = np.subtract(grey32, predicted)
        np.abs(residual, out=residual)
        scale = np.maximum(MAD_TO_SIGMA * median(residual, weights > 0), floor)
        inverse = np.divide(1.0, TUKEY_C * scale, out=np.zeros_like(scale), where=scale > 0)
        u = np.multiply(residual, inverse.astype(np.float32), out=residual)
        # Tukey's biweight (1 − u²)²₊ with u = residual / (c · scale), in place.
        u2 = np.square(u, out=u)
        tukey = np.square(np.clip(np.subtract(1.0, u2, out=u2), 0.0, None, out=u2), out=u2)
        # An observation the current fit puts in attached shadow carries no information.
        weights = np.multiply(tukey, support & (predicted > shadow_level), out=tukey)
    return weights


def reference_level(grey: np.ndarray, highlight_fraction: float) -> np.ndarray:
    """Each pixel's brightest observation once the top ``highlight_fraction`` of its
    lights are dropped (at least 3 kept): (n,) from (L, n)."""
    n_lights = grey.shape[0]
    dropped = max(0, min(int(highlight_fraction * n_lights), n_lights - 3))
    return np.sort(grey, axis=0)[n_lights - 1 - dropped]


def moment(lights: np.ndarray, weights: np.ndarray, grey: np.ndarray) -> np.ndarray:
    """Σ_l w I s per pixel: (n, 3), lights (L, 3) or one vector per pixel (L, n, 3)."""
    per_pixel = lights if lights.ndim == 3 else np.broadcast_to(
        lights[:, None, :], (*grey.shape, 3)
    )
    return np.einsum("lni,ln->ni", per_pixel, weights * grey)


def solve(a: np.ndarray, rhs: np.ndarray, solvable: np.ndarray) -> np.ndarray:
    """x with a x = rhs where ``solvable``, 0 elsewhere: (n, 3)."""
    x = np.zeros_like(rhs)
    x[solvable] = np.linalg.solve(a[solvable], rhs[solvable][..., None])[..., 0]
    return x


def median(magnitude: np.ndarray, support: np.ndarray) -> np.ndarray:
    """Per-pixel median of ``magnitude`` (L, n), ≥ 0, over the supported observations.

    0 where a pixel has none. Sorted pixel by pixel in contiguous float32 rows
    (sorting along the light axis of the (L, n) layout is 5–10× slower; the
    scale needs no more than float32's digits). Dividing by ``support`` masks,
    converts and transposes in one pass: unsupported entries become inf or
    NaN, which both sort last.
    """
    n_lights, n = magnitude.shape
    rows = np.empty((n, n_lights), np.float32)
    with np.errstate(divide="ignore", invalid="ignore"):
        np.divide(magnitude, support, out=rows.T, casting="same_kind")
    rows.sort(axis=1)
    count = support.sum(axis=0)
    lower = np.clip((count - 1) // 2, 0, None)
    upper = np.clip(count // 2, 0, None)
    lo = np.take_along_axis(rows, lower[:, None], axis=1)[:, 0]
    hi = np.take_along_axis(rows, upper[:, None], axis=1)[:, 0]
    median = 0.5 * (lo.astype(np.float64) + hi)
    return np.where(count > 0, median, 0.0)


def near_light_vectors(positions_mm, brightness, points_mm):
    """Point lamps' light vectors (L, N, 3): unit direction × brightness × (r0 / r)²."""
    to_lamp = positions_mm[:, None, :] - points_mm[None, :, :]
    r2 = np.einsum("lni,lni->ln", to_lamp, to_lamp)
    r0_sq = np.einsum("li,li->l", positions_mm, positions_mm)
    scale = (brightness * r0_sq)[:, None] / (r2 * np.sqrt(r2))
    return to_lamp * scale[..., None]
