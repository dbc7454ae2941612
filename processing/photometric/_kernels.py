"""Compiled loops of the pseudo-inverse route (numba, cached on disk).

Each kernel walks a tile of pixels light by light, so every inner loop runs
over contiguous pixels of one image and the per-pixel accumulators of the tile
stay in cache: the stack is read from memory once and the arithmetic is SIMD
over pixels. Habits that keep LLVM vectorising: the loops run over 1-D slices
of C-contiguous arrays (an indexed 2-D access blocks it); per-pixel decisions
are counts (``count += v >= level``) instead of running maxima (a float
``max`` compiles to a branch per sample and runs ~4× slower); levels are in
the work dtype (a float64 comparison halves the SIMD width). Lights are
taken ``_UNROLL`` at a time, so each accumulator is loaded and stored once
per group instead of once per light (stores bound these loops).

The first call for a dtype compiles (about 1 s per kernel and dtype); the
machine code is cached next to this module, so later processes load it.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from processing._numba_cache import keep_fresh

from . import _result
from ._result import CONDITION_CAP, Reason

_OK, _DARK, _BELOW_HORIZON = int(Reason.OK), int(Reason.DARK), int(Reason.BELOW_HORIZON)
_CAP = CONDITION_CAP
_CAP_SQ = _CAP * _CAP

# Fused multiply-add only: no assumption that values are finite (a clipping
# level may be inf, a bad pixel NaN; both must compare as IEEE says).
_CONTRACT = {"contract"}
#: Pixels per tile: the tile's accumulators stay in L1, its images in L2.
TILE = 1024


_UNROLL = 4


@njit(inline="always")
def add_normal_sums4(upper, lights, weights, m):
    """Add four lights' ``w s sᵀ`` to a tile's normal matrices.

    upper : six (m,) accumulators, the upper triangle (00, 01, 02, 11, 12, 22);
    lights : four (3,) light vectors; weights : the four lights' (m,) weights.
    Three accumulators or fewer per loop (more stop LLVM vectorising it).
    """
    a00, a01, a02, a11, a12, a22 = upper
    sa, sb, sc, sd = lights
    wa, wb, wc, wd = weights
    for acc, p, q in ((a00, 0, 0), (a01, 0, 1), (a02, 0, 2), (a11, 1, 1), (a12, 1, 2), (a22, 2, 2)):
        ca, cb, cc, cd = sa[p] * sa[q], sb[p] * sb[q], sc[p] * sc[q], sd[p] * sd[q]
        for i in range(m):
            acc[i] += ca * wa[i] + cb * wb[i] + cc * wc[i] + cd * wd[i]


@njit(inline="always")
def add_moments4(moment, lights, weights, obs, m):
    """Add four lights' ``w I s`` to a tile's three moment accumulators (m,).

    lights : four (3,) light vectors; weights, obs : the four lights' (m,)
    weights and observations.
    """
    sa, sb, sc, sd = lights
    wa, wb, wc, wd = weights
    ra, rb, rc, rd = obs
    for acc, p in ((moment[0], 0), (moment[1], 1), (moment[2], 2)):
        ca, cb, cc, cd = sa[p], sb[p], sc[p], sd[p]
        for i in range(m):
            acc[i] += (
                ca * wa[i] * ra[i] + cb * wb[i] * rb[i] + cc * wc[i] * rc[i] + cd * wd[i] * rd[i]
            )


@njit(inline="always")
def add_normal_sums1(upper, light, w, m):
    """:func:`add_normal_sums4` of one light: light (3,), w (m,)."""
    a00, a01, a02, a11, a12, a22 = upper
    s0, s1, s2 = light[0], light[1], light[2]
    p00, p01, p02, p11, p12, p22 = s0 * s0, s0 * s1, s0 * s2, s1 * s1, s1 * s2, s2 * s2
    for i in range(m):
        a00[i] += p00 * w[i]
        a01[i] += p01 * w[i]
        a02[i] += p02 * w[i]
    for i in range(m):
        a11[i] += p11 * w[i]
        a12[i] += p12 * w[i]
        a22[i] += p22 * w[i]


@njit(inline="always")
def add_moments1(moment, light, w, row, m):
    """:func:`add_moments4` of one light: light (3,), w and row (m,)."""
    g0, g1, g2 = moment
    s0, s1, s2 = light[0], light[1], light[2]
    for i in range(m):
        wi = w[i] * row[i]
        g0[i] += s0 * wi
        g1[i] += s1 * wi
        g2[i] += s2 * wi


@njit(cache=True, nogil=True, fastmath=_CONTRACT)
def pinv_moments(values, start, count, pinv_gain, clip_raw, dark_raw, x_out, clipped, lit):
    """``x = S⁺ (g ∘ I)`` for pixels ``start … start + count`` of ``values``.

    Parameters
    ----------
    values : (L, N) C-contiguous, stored dtype
    pinv_gain : (3, L) work dtype
        The pseudo-inverse with each column scaled by its light's gain
        (stored value → normalised intensity).
    clip_raw : (L,) work dtype
        Stored value at or above which each light's observation is clipped.
    dark_raw : work dtype scalar
        Stored value at or below which an observation is dark.
    x_out : (3, count) work dtype
    clipped, lit : (count,) work dtype
        Out: how many observations are at or above their clipping level, and
        how many above the dark level (counted in a loop of its own over the
        rows, in L1: in the first loop it stops LLVM vectorising).
    """
    n_lights = values.shape[0]
    one = x_out.dtype.type(1)
    zero = x_out.dtype.type(0)
    for t0 in range(0, count, TILE):
        m = min(TILE, count - t0)
        lo = start + t0
        x0 = x_out[0, t0 : t0 + m]
        x1 = x_out[1, t0 : t0 + m]
        x2 = x_out[2, t0 : t0 + m]
        n_clipped = clipped[t0 : t0 + m]
        n_lit = lit[t0 : t0 + m]
        x0[:] = 0
        x1[:] = 0
        x2[:] = 0
        n_clipped[:] = 0
        n_lit[:] = 0
        full = n_lights - n_lights % _UNROLL
        for k in range(0, full, _UNROLL):
            ra = values[k, lo : lo + m]
            rb = values[k + 1, lo : lo + m]
            rc = values[k + 2, lo : lo + m]
            rd = values[k + 3, lo : lo + m]
            pa0, pa1, pa2 = pinv_gain[0, k], pinv_gain[1, k], pinv_gain[2, k]
            pb0, pb1, pb2 = pinv_gain[0, k + 1], pinv_gain[1, k + 1], pinv_gain[2, k + 1]
            pc0, pc1, pc2 = pinv_gain[0, k + 2], pinv_gain[1, k + 2], pinv_gain[2, k + 2]
            pd0, pd1, pd2 = pinv_gain[0, k + 3], pinv_gain[1, k + 3], pinv_gain[2, k + 3]
            ca, cb, cc, cd = clip_raw[k], clip_raw[k + 1], clip_raw[k + 2], clip_raw[k + 3]
            for i in range(m):
                a, b, c, d = ra[i], rb[i], rc[i], rd[i]
                x0[i] += pa0 * a + pb0 * b + pc0 * c + pd0 * d
                x1[i] += pa1 * a + pb1 * b + pc1 * c + pd1 * d
                x2[i] += pa2 * a + pb2 * b + pc2 * c + pd2 * d
                n_clipped[i] += (
                    (one if a >= ca else zero)
                    + (one if b >= cb else zero)
                    + (one if c >= cc else zero)
                    + (one if d >= cd else zero)
                )
            for i in range(m):
                n_lit[i] += (
                    (one if ra[i] > dark_raw else zero)
                    + (one if rb[i] > dark_raw else zero)
                    + (one if rc[i] > dark_raw else zero)
                    + (one if rd[i] > dark_raw else zero)
                )
        for k in range(full, n_lights):
            row = values[k, lo : lo + m]
            p0, p1, p2, clip = pinv_gain[0, k], pinv_gain[1, k], pinv_gain[2, k], clip_raw[k]
            for i in range(m):
                v = row[i]
                x0[i] += p0 * v
                x1[i] += p1 * v
                x2[i] += p2 * v
                n_clipped[i] += one if v >= clip else zero
            for i in range(m):
                n_lit[i] += one if row[i] > dark_raw else zero


@njit(cache=True, nogil=True, fastmath=_CONTRACT)
def residual_squares(values, start, count, gain, lights, fit, out):
    """``Σ_l (g_l I_l − s_l · y)²`` per pixel, ``y`` the fitted vector: (count,).

    values : (L, N) C-contiguous; gain : (L,) work dtype; lights : (L, 3)
    work dtype; fit : (3, count) work dtype; out : (count,) work dtype.
    """
    n_lights = values.shape[0]
    for t0 in range(0, count, TILE):
        m = min(TILE, count - t0)
        lo = start + t0
        y0 = fit[0, t0 : t0 + m]
        y1 = fit[1, t0 : t0 + m]
        y2 = fit[2, t0 : t0 + m]
        sq = out[t0 : t0 + m]
        sq[:] = 0
        full = n_lights - n_lights % _UNROLL
        for k in range(0, full, _UNROLL):
            ra = values[k, lo : lo + m]
            rb = values[k + 1, lo : lo + m]
            rc = values[k + 2, lo : lo + m]
            rd = values[k + 3, lo : lo + m]
            ga, gb, gc, gd = gain[k], gain[k + 1], gain[k + 2], gain[k + 3]
            sa0, sa1, sa2 = lights[k, 0], lights[k, 1], lights[k, 2]
            sb0, sb1, sb2 = lights[k + 1, 0], lights[k + 1, 1], lights[k + 1, 2]
            sc0, sc1, sc2 = lights[k + 2, 0], lights[k + 2, 1], lights[k + 2, 2]
            sd0, sd1, sd2 = lights[k + 3, 0], lights[k + 3, 1], lights[k + 3, 2]
            for i in range(m):
                u0, u1, u2 = y0[i], y1[i], y2[i]
                a = ga * ra[i] - (sa0 * u0 + sa1 * u1 + sa2 * u2)
                b = gb * rb[i] - (sb0 * u0 + sb1 * u1 + sb2 * u2)
                c = gc * rc[i] - (sc0 * u0 + sc1 * u1 + sc2 * u2)
                d = gd * rd[i] - (sd0 * u0 + sd1 * u1 + sd2 * u2)
                sq[i] += a * a + b * b + c * c + d * d
        for k in range(full, n_lights):
            row = values[k, lo : lo + m]
            g, s0, s1, s2 = gain[k], lights[k, 0], lights[k, 1], lights[k, 2]
            for i in range(m):
                r = g * row[i] - (s0 * y0[i] + s1 * y1[i] + s2 * y2[i])
                sq[i] += r * r


@njit(cache=True, nogil=True)
def pinv_normals(moments, normals, albedo, fit):
    """Unit normals, per-channel albedo and the fitted vectors from the moments.

    moments : (C, 3, n) — ``x_c`` per channel; normals : (3, n) out, 0 where
    ``|mean_c x_c|`` is 0; albedo : (C, n) out, ``x_c · n``; fit : (C, 3, n)
    out, ``n · albedo_c`` (the vector the residual of channel c is taken
    against).
    """
    n_channels, _, n = moments.shape
    for i in range(n):
        b0 = b1 = b2 = 0.0
        for c in range(n_channels):
            b0 += moments[c, 0, i]
            b1 += moments[c, 1, i]
            b2 += moments[c, 2, i]
        rho = np.sqrt(b0 * b0 + b1 * b1 + b2 * b2)
        if rho > 0:
            b0, b1, b2 = b0 / rho, b1 / rho, b2 / rho
        else:
            b0 = b1 = b2 = 0.0
        normals[0, i], normals[1, i], normals[2, i] = b0, b1, b2
        for c in range(n_channels):
            a = moments[c, 0, i] * b0 + moments[c, 1, i] * b1 + moments[c, 2, i] * b2
            albedo[c, i] = a
            fit[c, 0, i], fit[c, 1, i], fit[c, 2, i] = b0 * a, b1 * a, b2 * a


@njit(cache=True, nogil=True)
def pinv_store(normals, albedo, sq, clipped, lit, pixel, n_lights, condition, out, hard):
    """Classify the route's pixels and write them into the result arrays.

    normals (3, n), albedo (C, n), sq (n,) Σ squared misfit over lights and
    channels, clipped (n,) and lit (C, n) counts; pixel (n,) their flat
    indices in ``out`` = (normals (N, 3), albedo (N, C), reason, condition,
    residual, lights_used), all of N pixels. ``hard`` (n,) out: the pixels
    the per-pixel route must solve (it overwrites their entries in ``out``).
    """
    out_normals, out_albedo, out_reason, out_condition, out_residual, out_used = out
    n_channels, n = albedo.shape
    for i in range(n):
        some = False
        every = True
        for c in range(n_channels):
            some |= lit[c, i] > 0
            every &= lit[c, i] > 0
        residual = np.sqrt(sq[i] / (n_lights * n_channels))
        # A colour pixel dark in some channels only: its brightness (the mean
        # of the channel maxima) needs the maxima, which the per-pixel route takes.
        hard[i] = clipped[i] > 0 or some != every or not np.isfinite(residual)
        flat = normals[0, i] == 0 and normals[1, i] == 0 and normals[2, i] == 0
        if not every or flat:
            reason = _DARK
        elif normals[2, i] < 0:
            reason = _BELOW_HORIZON
        else:
            reason = _OK
        p = pixel[i]
        out_reason[p] = reason
        out_condition[p] = condition
        out_used[p] = n_lights
        valid = reason == _OK
        out_normals[p, 0] = normals[0, i] if valid else 0.0
        out_normals[p, 1] = normals[1, i] if valid else 0.0
        out_normals[p, 2] = normals[2, i] if valid else 1.0
        for c in range(n_channels):
            out_albedo[p, c] = albedo[c, i] if valid else 0.0
        out_residual[p] = residual if valid else 0.0


def sum_arrays(n: int, n_channels: int) -> tuple:
    """Empty outputs of :func:`weighted_sums` for n pixels: upper, moment, energy,
    weight_sum, used."""
    return (
        np.empty((6, n)),
        np.empty((n_channels, 3, n)),
        np.empty((n_channels, n)),
        np.empty(n),
        np.empty(n),
    )


@njit(cache=True, nogil=True, fastmath=_CONTRACT)
def weighted_sums(weights, planes, lights, upper, moment, energy, weight_sum, used):
    """The per-pixel sums of a weighted fit with one shared light matrix, in one pass.

    weights : (L, n) float32 or float64; planes : (C, L, n) float64 observations per
    channel; lights : (L, 3) float64. Out: upper (6, n) ``Σ w s_i s_j`` for
    (i, j) in (00, 01, 02, 11, 12, 22); moment (C, 3, n) ``Σ w I s``; energy
    (C, n) ``Σ w I²``; weight_sum (n,) ``Σ w``; used (n,) float64, the
    observations with a non-zero weight.
    """
    n = weights.shape[1]
    for t0 in range(0, n, TILE):
        weighted_sums_tile(
            weights, planes, lights, t0, min(TILE, n - t0), upper, moment, energy, weight_sum, used
        )


@njit(inline="always")
def cleared_tile(upper, moment, energy, weight_sum, used, t0, m):
    """Pixels ``t0 … t0 + m`` of the sums, zeroed; their normal-matrix rows, Σ w and count."""
    a00, a01, a02 = upper[0, t0 : t0 + m], upper[1, t0 : t0 + m], upper[2, t0 : t0 + m]
    a11, a12, a22 = upper[3, t0 : t0 + m], upper[4, t0 : t0 + m], upper[5, t0 : t0 + m]
    total, count = weight_sum[t0 : t0 + m], used[t0 : t0 + m]
    for acc in (a00, a01, a02, a11, a12, a22, total, count):
        acc[:] = 0
    for c in range(moment.shape[0]):
        moment[c, :, t0 : t0 + m] = 0
        energy[c, t0 : t0 + m] = 0
    return a00, a01, a02, a11, a12, a22, total, count


@njit(cache=True, nogil=True, fastmath=_CONTRACT)
def weighted_sums_tile(weights, planes, lights, t0, m, upper, moment, energy, weight_sum, used):
    """:func:`weighted_sums` of pixels ``t0 … t0 + m``.

    Lights ``_UNROLL`` at a time, three accumulators or fewer per loop (more
    stop LLVM vectorising it).
    """
    n_lights = weights.shape[0]
    n_channels = planes.shape[0]
    one, zero = 1.0, 0.0
    a00, a01, a02, a11, a12, a22, total, count = cleared_tile(
        upper, moment, energy, weight_sum, used, t0, m
    )
    upper6 = (a00, a01, a02, a11, a12, a22)
    full = n_lights - n_lights % _UNROLL
    for k in range(0, full, _UNROLL):
        four = (lights[k], lights[k + 1], lights[k + 2], lights[k + 3])
        wa, wb = weights[k, t0 : t0 + m], weights[k + 1, t0 : t0 + m]
        wc, wd = weights[k + 2, t0 : t0 + m], weights[k + 3, t0 : t0 + m]
        add_normal_sums4(upper6, four, (wa, wb, wc, wd), m)
        for i in range(m):
            # In float64 from the first term on (float32 weights would sum in float32).
            total[i] += np.float64(wa[i]) + wb[i] + wc[i] + wd[i]
        for i in range(m):
            count[i] += (
                (one if wa[i] != 0 else zero)
                + (one if wb[i] != 0 else zero)
                + (one if wc[i] != 0 else zero)
                + (one if wd[i] != 0 else zero)
            )
        for c in range(n_channels):
            ra, rb = planes[c, k, t0 : t0 + m], planes[c, k + 1, t0 : t0 + m]
            rc, rd = planes[c, k + 2, t0 : t0 + m], planes[c, k + 3, t0 : t0 + m]
            g = (moment[c, 0, t0 : t0 + m], moment[c, 1, t0 : t0 + m], moment[c, 2, t0 : t0 + m])
            add_moments4(g, four, (wa, wb, wc, wd), (ra, rb, rc, rd), m)
            e = energy[c, t0 : t0 + m]
            for i in range(m):
                e[i] += (
                    wa[i] * ra[i] * ra[i]
                    + wb[i] * rb[i] * rb[i]
                    + wc[i] * rc[i] * rc[i]
                    + wd[i] * rd[i] * rd[i]
                )
    for light in range(full, n_lights):
        w = weights[light, t0 : t0 + m]
        add_normal_sums1(upper6, lights[light], w, m)
        for i in range(m):
            total[i] += w[i]
            count[i] += one if w[i] != 0 else zero
        for c in range(n_channels):
            row = planes[c, light, t0 : t0 + m]
            g = (moment[c, 0, t0 : t0 + m], moment[c, 1, t0 : t0 + m], moment[c, 2, t0 : t0 + m])
            add_moments1(g, lights[light], w, row, m)
            e = energy[c, t0 : t0 + m]
            for i in range(m):
                e[i] += w[i] * row[i] * row[i]


@njit(cache=True, nogil=True)
def conditions(upper, out):
    """:func:`condition3` of each pixel's normal matrix from its upper triangle (6, n): (n,)."""
    for i in range(upper.shape[1]):
        out[i] = condition3(upper[0, i], upper[1, i], upper[2, i], upper[3, i], upper[4, i],
                            upper[5, i])  # fmt: skip


@njit(cache=True, nogil=True)
def condition3(a00, a01, a02, a11, a12, a22):
    """sqrt(λmax/λmin) of a symmetric 3×3 matrix (its upper triangle).

    Closed-form eigenvalues of the characteristic cubic (Smith, CACM 4(4), 1961);
    ``CONDITION_CAP`` where the matrix is singular or zero.
    """
    q = (a00 + a11 + a22) / 3.0
    off = a01 * a01 + a02 * a02 + a12 * a12
    diag = (a00 - q) ** 2 + (a11 - q) ** 2 + (a22 - q) ** 2
    p = np.sqrt((diag + 2.0 * off) / 6.0)
    if p <= np.finfo(np.float64).tiny:
        hi = lo = q
    else:
        b00, b11, b22 = (a00 - q) / p, (a11 - q) / p, (a22 - q) / p
        b01, b02, b12 = a01 / p, a02 / p, a12 / p
        det = (
            b00 * (b11 * b22 - b12 * b12)
            - b01 * (b01 * b22 - b12 * b02)
            + b02 * (b01 * b12 - b11 * b02)
        )
        phi = np.arccos(min(max(det / 2.0, -1.0), 1.0)) / 3.0
        hi = q + 2.0 * p * np.cos(phi)
        lo = q + 2.0 * p * np.cos(phi + 2.0 * np.pi / 3.0)
    if hi > 0 and lo > hi / _CAP_SQ:
        return np.sqrt(hi / lo)
    return _CAP


@njit(inline="always")
def cofactors3(a00, a01, a02, a11, a12, a22):
    """The adjugate (upper triangle) and the determinant of a symmetric 3×3 matrix."""
    c00 = a11 * a22 - a12 * a12
    c01 = a02 * a12 - a01 * a22
    c02 = a01 * a12 - a02 * a11
    c11 = a00 * a22 - a02 * a02
    c12 = a01 * a02 - a00 * a12
    c22 = a00 * a11 - a01 * a01
    return c00, c01, c02, c11, c12, c22, a00 * c00 + a01 * c01 + a02 * c02


@njit(cache=True, nogil=True)
def fit_from_sums(
    upper, moment, energy, weight_sum, used, condition, max_condition, normals, albedo, residual,
    positive,
):  # fmt: skip
    """The fit of each pixel from the sums of :func:`weighted_sums`, as ``_block._fit`` gives it.

    Where ``used ≥ 3`` and ``condition ≤ max_condition``: ``x = A⁻¹ g`` by the
    adjugate (g: the mean over channels), normal ``x / |x|``, albedo ``|x|``
    (colour: ``A⁻¹ g_c · n`` per channel), residual ``√(Σ_c (e − 2 ρ n·g + ρ² nᵀAn)₊ /
    (C Σ w))``. Out: normals (n, 3), 0 where not solved or ``|x|`` is 0; albedo (n, C);
    residual (n,); positive (n,) bool, solved with ``|x| > 0``.
    """
    n_channels, _, n = moment.shape
    for i in range(n):
        a00, a01, a02 = upper[0, i], upper[1, i], upper[2, i]
        a11, a12, a22 = upper[3, i], upper[4, i], upper[5, i]
        c00, c01, c02, c11, c12, c22, det = cofactors3(a00, a01, a02, a11, a12, a22)
        solvable = used[i] >= 3 and condition[i] <= max_condition
        inv = 1.0 / det if solvable and det != 0 else 0.0
        i00, i01, i02 = c00 * inv, c01 * inv, c02 * inv
        i11, i12, i22 = c11 * inv, c12 * inv, c22 * inv
        g0 = g1 = g2 = 0.0
        for c in range(n_channels):
            g0 += moment[c, 0, i]
            g1 += moment[c, 1, i]
            g2 += moment[c, 2, i]
        g0, g1, g2 = g0 / n_channels, g1 / n_channels, g2 / n_channels
        x0 = i00 * g0 + i01 * g1 + i02 * g2
        x1 = i01 * g0 + i11 * g1 + i12 * g2
        x2 = i02 * g0 + i12 * g1 + i22 * g2
        rho = np.sqrt(x0 * x0 + x1 * x1 + x2 * x2)
        solved = solvable and rho > 0
        n0, n1, n2 = (x0 / rho, x1 / rho, x2 / rho) if solved else (0.0, 0.0, 0.0)
        n_a_n = (
            n0 * (a00 * n0 + a01 * n1 + a02 * n2)
            + n1 * (a01 * n0 + a11 * n1 + a12 * n2)
            + n2 * (a02 * n0 + a12 * n1 + a22 * n2)
        )
        sq = 0.0
        for c in range(n_channels):
            m0, m1, m2 = moment[c, 0, i], moment[c, 1, i], moment[c, 2, i]
            if n_channels > 1:
                y0 = i00 * m0 + i01 * m1 + i02 * m2
                y1 = i01 * m0 + i11 * m1 + i12 * m2
                y2 = i02 * m0 + i12 * m1 + i22 * m2
                rho_c = y0 * n0 + y1 * n1 + y2 * n2
            else:
                rho_c = rho
            along = n0 * m0 + n1 * m1 + n2 * m2
            sq += max(energy[c, i] - 2.0 * rho_c * along + rho_c * rho_c * n_a_n, 0.0)
            albedo[i, c] = rho_c
        sq /= n_channels
        normals[i, 0], normals[i, 1], normals[i, 2] = n0, n1, n2
        residual[i] = np.sqrt(sq / weight_sum[i]) if weight_sum[i] > 0 else 0.0
        positive[i] = solved


keep_fresh(__name__, _result)
