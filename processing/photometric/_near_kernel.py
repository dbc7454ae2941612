"""The per-pixel route's sums for near lamps, compiled: a light vector per pixel.

Near lamps give every pixel its own light vectors, taken here as three
C-contiguous planes ``(3, L, n)`` (x, y, z of every light and pixel), so each
inner loop runs over contiguous pixels of one light, as in :mod:`._kernels`;
the sums are those of :func:`._kernels.weighted_sums`, with ``s`` varying
along the pixels, and the float32 sums of the IRLS steps
(:func:`._irls_kernel.irls_fit_kernel` takes either light layout). The planes
themselves are computed here too, from the lamp positions and the surface points.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from processing._numba_cache import keep_fresh

from . import _kernels, _result
from ._kernels import TILE, cleared_tile

# Fused multiply-add only: nothing assumes finite values.
_CONTRACT = {"contract"}


@njit(inline="always")
def add_near_moments(moment, light, w, row, m):
    """Add one light's ``w I s`` to a tile's three moment accumulators (m,), ``s`` per pixel.

    light : its x, y, z (m,) planes; w, row : its (m,) weights and observations.
    """
    g0, g1, g2 = moment
    s0, s1, s2 = light
    for i in range(m):
        wi = w[i] * row[i]
        g0[i] += s0[i] * wi
        g1[i] += s1[i] * wi
        g2[i] += s2[i] * wi


@njit(cache=True, nogil=True, fastmath=_CONTRACT)
def near_weighted_sums(weights, planes, lights, upper, moment, energy, weight_sum, used):
    """The per-pixel sums of a weighted fit with a light vector per pixel, in one pass.

    weights : (L, n) float32 or float64; planes : (C, L, n) float64 observations per
    channel (C may be 0: the normal matrices only); lights : (3, L, n) float64 light
    vectors per pixel. Out: as :func:`._kernels.weighted_sums` fills them.
    """
    n = weights.shape[1]
    for t0 in range(0, n, TILE):
        near_weighted_sums_tile(
            weights, planes, lights, t0, min(TILE, n - t0), upper, moment, energy, weight_sum, used
        )


@njit(cache=True, nogil=True, fastmath=_CONTRACT)
def near_weighted_sums_tile(
    weights, planes, lights, t0, m, upper, moment, energy, weight_sum, used
):  # fmt: skip
    """:func:`near_weighted_sums` of pixels ``t0 … t0 + m``."""
    n_lights = weights.shape[0]
    n_channels = planes.shape[0]
    one, zero = 1.0, 0.0
    a00, a01, a02, a11, a12, a22, total, count = cleared_tile(
        upper, moment, energy, weight_sum, used, t0, m
    )
    for light in range(n_lights):
        w = weights[light, t0 : t0 + m]
        s0 = lights[0, light, t0 : t0 + m]
        s1 = lights[1, light, t0 : t0 + m]
        s2 = lights[2, light, t0 : t0 + m]
        for i in range(m):
            ws = w[i] * s0[i]
            a00[i] += ws * s0[i]
            a01[i] += ws * s1[i]
            a02[i] += ws * s2[i]
        for i in range(m):
            ws = w[i] * s1[i]
            a11[i] += ws * s1[i]
            a12[i] += ws * s2[i]
        for i in range(m):
            a22[i] += w[i] * s2[i] * s2[i]
            total[i] += w[i]
            count[i] += one if w[i] != 0 else zero
        for c in range(n_channels):
            row = planes[c, light, t0 : t0 + m]
            g = (moment[c, 0, t0 : t0 + m], moment[c, 1, t0 : t0 + m], moment[c, 2, t0 : t0 + m])
            add_near_moments(g, (s0, s1, s2), w, row, m)
            e = energy[c, t0 : t0 + m]
            for i in range(m):
                e[i] += w[i] * row[i] * row[i]


@njit(cache=True, nogil=True, fastmath=_CONTRACT)
def near_light_planes(positions, gain, points, out):
    """Light vectors of point lamps at every point, as x, y, z planes.

    positions : (L, 3) float64 lamp positions; gain : (L,) float64, brightness ×
    r0² of each lamp; points : (3, n) float64 surface points (x, y, z rows).
    Out: out (3, L, n) float64, ``(p_l − x) · gain_l / |p_l − x|³``: the unit
    direction to the lamp × brightness × (r0 / r)².
    """
    n_lights, n = positions.shape[0], points.shape[1]
    px, py, pz = points[0], points[1], points[2]
    for light in range(n_lights):
        lx, ly, lz, g = positions[light, 0], positions[light, 1], positions[light, 2], gain[light]
        ox, oy, oz = out[0, light], out[1, light], out[2, light]
        for i in range(n):
            dx, dy, dz = lx - px[i], ly - py[i], lz - pz[i]
            r2 = dx * dx + dy * dy + dz * dz
            scale = g / (r2 * np.sqrt(r2))
            ox[i] = dx * scale
            oy[i] = dy * scale
            oz[i] = dz * scale


@njit(cache=True, nogil=True, fastmath=_CONTRACT)
def near_light_sums(weights, grey, lights, t0, m, sums):
    """Float32 ``Σ w s sᵀ`` (6 rows) and ``Σ w I s`` (3 rows) of a tile for the IRLS steps.

    weights : (L, n), pixels ``t0 … t0 + m``; grey : (L, ≥ m), the tile's
    observations; lights : (3, L, n) float32; sums : (9, m) float32, added to.
    """
    n_lights = grey.shape[0]
    m00, m01, m02, m11, m12, m22 = sums[0], sums[1], sums[2], sums[3], sums[4], sums[5]
    g0s, g1s, g2s = sums[6], sums[7], sums[8]
    for light in range(n_lights):
        w = weights[light, t0 : t0 + m]
        row = grey[light, :m]
        s0 = lights[0, light, t0 : t0 + m]
        s1 = lights[1, light, t0 : t0 + m]
        s2 = lights[2, light, t0 : t0 + m]
        for i in range(m):
            ws = w[i] * s0[i]
            m00[i] += ws * s0[i]
            m01[i] += ws * s1[i]
            m02[i] += ws * s2[i]
        for i in range(m):
            ws = w[i] * s1[i]
            m11[i] += ws * s1[i]
            m12[i] += ws * s2[i]
            m22[i] += w[i] * s2[i] * s2[i]
        add_near_moments((g0s, g1s, g2s), (s0, s1, s2), w, row, m)


keep_fresh(__name__, _kernels, _result)
