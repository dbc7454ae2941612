"""The IRLS reweighting of :mod:`._robust`, compiled: a few passes per step over a tile.

The same arithmetic as the numpy version (float32 observations, residuals and
weights, float64 3×3 systems), laid out like :mod:`._kernels`: a tile of
pixels, light by light, SIMD over pixels, everything in cache. The two order
statistics (the reference level and the median absolute residual) are exact
selections on order-preserving integer keys of the float32 values,
vectorised over the tile's pixels: counting passes in cache, bisecting each
pixel's key range until its answer is among a few keys (about 11 passes on
noisy data), instead of a transposing copy and a sort per pixel. Every step
of one pixel at a time on a transposed tile, with quickselects (branches that
mispredict), measured ~4× slower than this. With its final weights, each tile
also gets the float64 sums of the fit (:func:`._kernels.weighted_sums_tile`),
so the observations are read from memory once.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from processing._numba_cache import keep_fresh

from . import _kernels, _near_kernel, _result
from ._kernels import (
    add_moments1,
    add_moments4,
    add_normal_sums1,
    add_normal_sums4,
    cofactors3,
    condition3,
    weighted_sums_tile,
)
from ._near_kernel import near_light_sums, near_weighted_sums_tile

#: Pixels per tile: the tile's keys, residuals, weights and support (L × TILE
#: each) stay in L2 through the selection passes.
TILE = 256

# Fused multiply-add only: nothing assumes finite values.
_CONTRACT = {"contract"}
_LOW_BITS = np.int32(0x7FFFFFFF)
#: Key of an observation left out of the median: above every finite value's key.
_ABSENT = np.int32(0x7FFFFFFF)
#: A selection's bisection stops when every pixel's interval holds at most
#: this many keys; a last pass keeps the smallest ``_NEAR + 1`` of them.
_NEAR = 3
#: Lights per loop where per-pixel accumulators are summed over the lights.
_UNROLL = 4


@njit(cache=True, nogil=True, fastmath=_CONTRACT)
def irls_fit_kernel(grey, usable, lights, rank, settings, out, planes, lights64, sums):
    """Tukey-biweight IRLS weights of every pixel and the sums of the fit with them.

    Each tile of pixels is read once: reweighted in float32 and, with its final
    weights still in cache, summed in float64 for the fit the solver takes
    (:func:`._kernels.weighted_sums`, the sums it would take in a pass of its own).

    Parameters
    ----------
    grey : (L, n) float32 or float64, C-contiguous
    usable : (L, n) bool, C-contiguous (False: clipped)
    lights : (L, 3) float32, or (3, L, n) float32
        One light matrix, or a light vector per pixel (x, y, z planes: near lamps).
    rank : int
        Order of the reference level among a pixel's observations.
    settings : (6,) float64
        shadow_fraction, iterations, max_condition, Tukey c, MAD → σ, scale
        floor (relative to the reference level).
    out : (L, n) float32
        The weights.
    planes : (C, L, n) float64
        The observations per channel the final sums take (grey: ``grey[None]``).
    lights64 : (L, 3) or (3, L, n) float64
        The same lights in float64.
    sums : tuple of arrays
        Out: ``upper, moment, energy, weight_sum, used`` as
        :func:`._kernels.weighted_sums` fills them.
    """
    shadow_fraction, iterations, max_condition = settings[0], int(settings[1]), settings[2]
    tukey_c, mad_to_sigma, floor_fraction = settings[3], settings[4], settings[5]
    n_lights, n = grey.shape
    keys = np.empty((n_lights, TILE), np.int32)
    support = np.empty((n_lights, TILE), np.float32)
    residual = np.empty((n_lights, TILE), np.float32)
    order = np.empty(TILE, np.int32)
    count = np.empty(TILE, np.float32)
    lower = np.empty(TILE, np.int32)
    upper = np.empty(TILE, np.int32)
    values = np.empty(TILE, np.float32)
    shadow = np.empty(TILE, np.float32)
    inverse = np.empty(TILE, np.float32)
    floor = np.empty(TILE, np.float64)
    fit = np.empty((3, TILE), np.float32)
    f0, f1, f2 = fit[0], fit[1], fit[2]
    tile = np.empty((n_lights, TILE), np.float32)
    upper_sums, moment, energy, weight_sum, used = sums
    for t0 in range(0, n, TILE):
        m = min(TILE, n - t0)
        for light in range(n_lights):
            row, copy = grey[light, t0 : t0 + m], tile[light]
            for i in range(m):
                copy[i] = row[i]
        # The reference level: each pixel's observation of order `rank`.
        for light in range(n_lights):
            _float_keys(tile[light, :m], keys[light])
        order[:m] = rank
        _select(keys, m, order, lower, upper)
        _key_values(lower, m, values)
        for i in range(m):
            shadow[i] = np.float32(shadow_fraction * values[i])
            floor[i] = floor_fraction * max(np.float64(values[i]), 0.0)
        for light in range(n_lights):
            row = tile[light, :m]
            use = usable[light, t0 : t0 + m]
            sup = support[light]
            w = out[light, t0 : t0 + m]
            for i in range(m):
                on = use[i] and row[i] >= shadow_fraction * np.float64(values[i])
                sup[i] = 1.0 if on else 0.0
                w[i] = 1.0 if on and row[i] <= values[i] else 0.0
        for _ in range(iterations):
            _weighted_fit(out, tile, lights, t0, m, max_condition, fit)
            count[:m] = 0
            for light in range(n_lights):
                row = tile[light, :m]
                w = out[light, t0 : t0 + m]
                sup = support[light]
                res = residual[light]
                # |residual|, negated where the observation is out of the next
                # weights (unsupported, or in attached shadow under this fit):
                # the biweight below then reads one array instead of five.
                if lights.ndim == 2:  # one light vector for the tile (pruned when compiled)
                    s0, s1, s2 = lights[light, 0], lights[light, 1], lights[light, 2]
                    for i in range(m):
                        predicted = s0 * f0[i] + s1 * f1[i] + s2 * f2[i]
                        r = abs(row[i] - predicted)
                        res[i] = r if sup[i] > 0 and predicted > shadow[i] else -r
                else:
                    v0 = lights[0, light, t0 : t0 + m]
                    v1 = lights[1, light, t0 : t0 + m]
                    v2 = lights[2, light, t0 : t0 + m]
                    for i in range(m):
                        predicted = v0[i] * f0[i] + v1[i] * f1[i] + v2[i] * f2[i]
                        r = abs(row[i] - predicted)
                        res[i] = r if sup[i] > 0 and predicted > shadow[i] else -r
                bits = res.view(np.int32)
                key = keys[light]
                for i in range(m):
                    on = w[i] > 0
                    key[i] = bits[i] & _LOW_BITS if on else _ABSENT
                    count[i] += np.float32(1) if on else np.float32(0)
            for i in range(m):
                order[i] = max((np.int32(count[i]) - 1) // 2, 0)
            _select(keys, m, order, lower, upper)
            for i in range(m):
                lo = np.float64(_key_value(lower[i]))
                hi = np.float64(_key_value(upper[i])) if np.int32(count[i]) % 2 == 0 else lo
                median = 0.5 * (lo + hi) if count[i] > 0 else 0.0
                scale = max(mad_to_sigma * median, floor[i])
                inverse[i] = 1.0 / (tukey_c * scale) if scale > 0 else 0.0
            for light in range(n_lights):
                bits = residual[light].view(np.int32)
                res = residual[light]
                w = out[light, t0 : t0 + m]
                for i in range(m):
                    u = res[i] * inverse[i]
                    t = max(np.float32(1.0) - u * u, np.float32(0.0))
                    w[i] = t * t if bits[i] >= 0 else np.float32(0.0)
        if lights64.ndim == 2:
            weighted_sums_tile(
                out, planes, lights64, t0, m, upper_sums, moment, energy, weight_sum, used
            )
        else:
            near_weighted_sums_tile(
                out, planes, lights64, t0, m, upper_sums, moment, energy, weight_sum, used
            )


@njit(cache=True, nogil=True, fastmath=_CONTRACT)
def _weighted_fit(weights, grey, lights, t0, m, max_condition, fit):
    """``b = (Σ w s sᵀ)⁻¹ Σ w I s`` per pixel (0 where the system is too ill-conditioned).

    weights : (L, n), pixels ``t0 … t0 + m``; grey : (L, ≥ m), the tile's observations.
    """
    sums = np.zeros((9, m), np.float32)
    if lights.ndim == 2:  # one light matrix (pruned when compiled)
        _shared_light_sums(weights, grey, lights, t0, m, sums)
    else:
        near_light_sums(weights, grey, lights, t0, m, sums)
    for i in range(m):
        a00, a01, a02 = np.float64(sums[0, i]), np.float64(sums[1, i]), np.float64(sums[2, i])
        a11, a12, a22 = np.float64(sums[3, i]), np.float64(sums[4, i]), np.float64(sums[5, i])
        g0, g1, g2 = np.float64(sums[6, i]), np.float64(sums[7, i]), np.float64(sums[8, i])
        c00, c01, c02, c11, c12, c22, det = cofactors3(a00, a01, a02, a11, a12, a22)
        if det != 0 and _within_condition(a00, a01, a02, a11, a12, a22, det, max_condition):
            fit[0, i] = (c00 * g0 + c01 * g1 + c02 * g2) / det
            fit[1, i] = (c01 * g0 + c11 * g1 + c12 * g2) / det
            fit[2, i] = (c02 * g0 + c12 * g1 + c22 * g2) / det
        else:
            fit[0, i] = fit[1, i] = fit[2, i] = 0.0


@njit(cache=True, nogil=True, fastmath=_CONTRACT)
def _shared_light_sums(weights, grey, lights, t0, m, sums):
    """Float32 ``Σ w s sᵀ`` (6 rows) and ``Σ w I s`` (3 rows) of a tile, lights (L, 3)."""
    n_lights = grey.shape[0]
    upper = (sums[0], sums[1], sums[2], sums[3], sums[4], sums[5])
    moment = (sums[6], sums[7], sums[8])
    # Four lights per loop: each accumulator is loaded and stored once per four
    # (stores bound these loops).
    full = n_lights - n_lights % _UNROLL
    for k in range(0, full, _UNROLL):
        four = (lights[k], lights[k + 1], lights[k + 2], lights[k + 3])
        wa, wb = weights[k, t0 : t0 + m], weights[k + 1, t0 : t0 + m]
        wc, wd = weights[k + 2, t0 : t0 + m], weights[k + 3, t0 : t0 + m]
        add_normal_sums4(upper, four, (wa, wb, wc, wd), m)
        add_moments4(
            moment,
            four,
            (wa, wb, wc, wd),
            (grey[k, :m], grey[k + 1, :m], grey[k + 2, :m], grey[k + 3, :m]),
            m,
        )
    for light in range(full, n_lights):
        w = weights[light, t0 : t0 + m]
        add_normal_sums1(upper, lights[light], w, m)
        add_moments1(moment, lights[light], w, grey[light, :m], m)


@njit(cache=True, nogil=True)
def _within_condition(a00, a01, a02, a11, a12, a22, det, max_condition):
    """Whether a weighted normal matrix (positive semi-definite) has condition ≤ ``max_condition``.

    Cheap certificate first: with eigenvalues λ1 ≥ λ2 ≥ λ3, λ1 ≤ tr and
    λ1 λ2 ≤ tr² / 4, so cond² = λ1 / λ3 ≤ tr³ / (4 det). Well-spread lamps
    pass it by orders of magnitude; only the rest pay the eigenvalues
    (the trigonometric form, ~130 ns a pixel).
    """
    trace = a00 + a11 + a22
    if det > 0 and trace * trace * trace <= 4.0 * det * max_condition * max_condition:
        return True
    return condition3(a00, a01, a02, a11, a12, a22) <= max_condition


@njit(cache=True, nogil=True)
def _select(keys, m, order, lower, upper):
    """Per pixel, the keys of order ``order`` and ``order + 1`` (0 = smallest) among the L keys.

    Exact. Bisection of each pixel's key range, from its smallest key to its
    largest present one: halve the interval, keeping the half that holds
    the key of order ``order``. Keys are ~2²³ log2 of the values, so the
    passes it takes follow how spread the values are (about 10 on noisy
    residuals), not the 32 bits. It stops as soon as every pixel's interval
    holds at most ``_NEAR`` keys; one last pass then keeps each pixel's
    ``_NEAR + 1`` smallest keys from the interval's start on, which hold
    both answers. Keys that tie all the way down leave an interval of one
    key: that key, or the smallest key above it.
    """
    n_lights = keys.shape[0]
    low = np.empty(m, np.int64)  # the answer lies in [low, high)
    high = np.empty(m, np.int64)
    candidate = np.empty(m, np.int32)
    # float32 counts: int32 sums widen to int64 lanes
    below = np.empty(m, np.float32)
    count_low = np.zeros(m, np.float32)  # keys < low
    count_high = np.zeros(m, np.float32)  # keys < high
    one, zero, near = np.float32(1), np.float32(0), np.float32(_NEAR)
    smallest = np.full(m, _ABSENT, np.int32)
    largest = np.full(m, np.int32(-(2**31)), np.int32)  # of the present keys
    for light in range(n_lights):
        row = keys[light]
        for i in range(m):
            smallest[i] = min(smallest[i], row[i])
            largest[i] = max(largest[i], row[i] if row[i] != _ABSENT else largest[i])
        for i in range(m):
            count_high[i] += one if row[i] != _ABSENT else zero
    for i in range(m):
        low[i] = smallest[i]
        high[i] = max(np.int64(largest[i]) + 1, low[i] + 1)
    while True:
        spread = zero
        for i in range(m):
            wide = count_high[i] - count_low[i] > near and high[i] - low[i] > 1
            spread += one if wide else zero
        if spread == 0:
            break
        for i in range(m):
            candidate[i] = np.int32(low[i] + ((high[i] - low[i]) >> 1))
        below[:] = 0
        # Four lights per loop: `below` is loaded and stored once per four (stores bound it).
        full = n_lights - n_lights % _UNROLL
        for light in range(0, full, _UNROLL):
            ra, rb, rc, rd = keys[light], keys[light + 1], keys[light + 2], keys[light + 3]
            for i in range(m):
                c = candidate[i]
                below[i] += (
                    (one if ra[i] < c else zero)
                    + (one if rb[i] < c else zero)
                    + (one if rc[i] < c else zero)
                    + (one if rd[i] < c else zero)
                )
        for light in range(full, n_lights):
            row = keys[light]
            for i in range(m):
                below[i] += one if row[i] < candidate[i] else zero
        for i in range(m):
            if below[i] <= order[i]:
                low[i] = candidate[i]
                count_low[i] = below[i]
            else:
                high[i] = candidate[i]
                count_high[i] = below[i]
    start = candidate  # the interval's start as int32, for int32 comparisons
    for i in range(m):
        start[i] = np.int32(low[i])
    t0 = np.full(m, _ABSENT, np.int32)
    t1, t2, t3, above = t0.copy(), t0.copy(), t0.copy(), t0.copy()
    for light in range(n_lights):
        row = keys[light]
        for i in range(m):
            above[i] = min(above[i], row[i] if row[i] > start[i] else _ABSENT)
        for i in range(m):
            k = row[i] if row[i] >= start[i] else _ABSENT
            # Insert k into t0 ≤ t1 ≤ t2 ≤ t3 (integer min and max vectorise).
            a = t0[i]
            t0[i] = min(a, k)
            k = max(a, k)
            a = t1[i]
            t1[i] = min(a, k)
            k = max(a, k)
            a = t2[i]
            t2[i] = min(a, k)
            t3[i] = min(t3[i], max(a, k))
    for i in range(m):
        r = order[i] - np.int32(count_low[i])
        inside = np.int32(count_high[i] - count_low[i])
        lower[i] = _pick(r, t0[i], t1[i], t2[i], t3[i], start[i])
        if r + 1 <= _NEAR:
            upper[i] = _pick(r + 1, t0[i], t1[i], t2[i], t3[i], start[i])
        else:  # an interval of one key, tied more than _NEAR times
            upper[i] = start[i] if r + 1 < inside else above[i]


@njit(cache=True, nogil=True)
def _pick(r, t0, t1, t2, t3, tied):
    """The tracked key of rank ``r``; ``tied`` (the interval's one key) past them."""
    if r == 0:
        return t0
    if r == 1:
        return t1
    if r == 2:
        return t2
    if r == 3:
        return t3
    return tied


@njit(cache=True, nogil=True)
def _float_keys(row, out):
    """int32 keys that order like the float32 values of ``row`` (negatives: low bits flipped)."""
    bits = row.view(np.int32)
    for i in range(row.shape[0]):
        x = bits[i]
        out[i] = x ^ ((x >> 31) & _LOW_BITS)


@njit(cache=True, nogil=True)
def _key_values(keys, m, out):
    """The float32 values behind keys of :func:`_float_keys` (the map is its own inverse)."""
    bits = out[:m].view(np.int32)
    for i in range(m):
        x = keys[i]
        bits[i] = x ^ ((x >> 31) & _LOW_BITS)


@njit(cache=True, nogil=True)
def _key_value(key):
    """One non-negative value's float32 from its key (a median's middle observations)."""
    bits = np.empty(1, np.int32)
    bits[0] = key
    return bits.view(np.float32)[0]


keep_fresh(__name__, _kernels, _near_kernel, _result)
