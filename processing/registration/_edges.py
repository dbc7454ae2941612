"""Sub-pixel marker corners from straight-line fits to the marker's outer edges.

OpenCV's corner refinement (``cornerSubPix``) is built for saddle points; on
the convex corner of a black marker in a white quiet zone it is biased
outwards by ~0.2 px. Under a homography the marker's outer edges stay
straight, so each edge is located instead: along many normals through the
middle of an edge the grey level is sampled (bilinear) and the edge position
is found from the area under the normalised profile (a moment estimator,
unbiased for any symmetric blur, unlike a half-level crossing of the
interpolated samples, which is off by up to 1/8 px depending on the edge's
sub-pixel phase); a total least-squares line through those positions is
intersected with its neighbours' lines to give the corners.

Every marker of a frame is refined in one compiled call (numba, cached on
disk, without the GIL): as a Python loop of small numpy calls per edge it held
the GIL for about 40 % of an item of ``rig process`` and kept threads of one
Dask worker from running side by side. The arithmetic is that loop's, in
float64: bilinear samples as ``scipy.ndimage.map_coordinates(order=1,
mode="nearest")``, levels from medians, trapezoidal areas; the line's normal
is the 2 × 2 scatter matrix's minor axis in closed form instead of an SVD.
The first call compiles (13 s on a loaded 2-core machine); the machine code is
cached next to this module, so later processes load it (0.3 s).
"""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np
from numba import njit

from processing.registration._errors import RegistrationError

__all__ = ["fit_corners", "gray_image", "refine_corners"]

_SPAN = (0.15, 0.85)  # the part of each edge used, away from the corners
_STEPS_PER_PX = 8
_ITERATIONS = 2

# Scratch arrays of the edge fits of one call: t (n_normals,), offsets (n_steps,), base
# (n_normals, 2), profile (n_normals, n_steps), points (n_normals, 2) and the end levels
# (n_normals · n_steps,).
_ScratchArrays = namedtuple("_ScratchArrays", "t offsets base profile points levels")


def refine_corners(gray: np.ndarray, quads: np.ndarray, *, modules: int) -> np.ndarray:
    """Corners of markers from line fits to their four outer edges.

    Parameters
    ----------
    gray : (H, W) float64
        Grey image (any scale; black markers on a brighter plate), H, W ≥ 2.
    quads : (m, 4, 2) float64
        Initial corners (x = column, y = row) of each marker in OpenCV's order,
        good to a fraction of a module.
    modules : int
        Modules per marker side including the black border (bits + 2).

    Returns
    -------
    (m, 4, 2) float64
        The refined corners; a marker with an edge that could not be located
        (too little contrast, fewer than three clean normals, parallel edges,
        or a corner that would move by more than a module) keeps its ``quads``.
    """
    return fit_corners(gray, quads, modules=modules)[0]


def fit_corners(
    gray: np.ndarray, quads: np.ndarray, *, modules: int
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`refine_corners`, and which markers it refined.

    Returns
    -------
    corners : (m, 4, 2) float64
    ok : (m,) bool
    """
    image = np.ascontiguousarray(gray, dtype=np.float64)
    if image.ndim != 2 or min(image.shape) < 2:
        raise RegistrationError(f"gray: expected an (H, W) image, H, W ≥ 2, got {image.shape}")
    initial = np.ascontiguousarray(quads, dtype=np.float64)
    if initial.ndim != 3 or initial.shape[1:] != (4, 2):
        raise RegistrationError(f"quads: expected shape (m, 4, 2), got {initial.shape}")
    if modules < 1:
        raise RegistrationError(f"modules = {modules}: must be ≥ 1")
    refined = initial.copy()
    ok = np.zeros(len(refined), np.bool_)
    _refine_quads(image, refined, int(modules), ok)
    return refined, ok


def gray_image(frame: np.ndarray) -> np.ndarray:
    """(H, W) float64 mean over the channels of an (H, W, C) frame, C ∈ {1, 3}; NaN, ±inf → 0.

    One compiled pass (the channels summed in order, then / 3): numpy's casts,
    sums and ``nan_to_num`` made four passes and took a twentieth of a registration.
    """
    out = np.empty(frame.shape[:2])
    _gray_image(frame, out)
    return out


@njit(cache=True, nogil=True)
def _gray_image(frame, out):
    for r in range(frame.shape[0]):
        for c in range(frame.shape[1]):
            if frame.shape[2] == 3:
                value = (float(frame[r, c, 0]) + frame[r, c, 1] + frame[r, c, 2]) / 3.0
            else:
                value = float(frame[r, c, 0])
            # value − value is 0 for every finite value and NaN for NaN and ±inf.
            out[r, c] = value if value - value == 0.0 else 0.0


@njit(cache=True, nogil=True)
def _refine_quads(gray, quads, modules, ok):
    """Refine every (4, 2) quad of ``quads`` in place, ``ok[i]`` where it succeeded;
    one that fails is left as it was."""
    corners = np.empty((4, 2))
    # Scratch for the edge fits, sized for the longest edge and widest reach any
    # round can reach (a corner moves by at most a module per round): allocated
    # once per call, not per edge.
    longest = 0.0
    for i in range(quads.shape[0]):
        for k in range(4):
            p0, p1 = quads[i, k], quads[i, (k + 1) % 4]
            side = math.hypot(p1[0] - p0[0], p1[1] - p0[1])
            if side == side:  # a NaN quad fails its first edge
                longest = max(longest, side)
    grown = longest * (1.0 + 2.0 * _ITERATIONS / modules)
    reach = 0.8 * grown / modules
    scratch = _scratch(_n_normals(grown), _n_steps(reach))
    for i in range(quads.shape[0]):
        corners[:] = quads[i]
        if _refine_quad(gray, corners, modules, scratch):
            quads[i] = corners
            ok[i] = True


@njit(cache=True, nogil=True)
def _refine_quad(gray, corners, modules, scratch):
    """Two rounds of edge fits on ``corners`` (4, 2), in place; False where one fails."""
    lines = np.empty((4, 3))  # per edge: normal x, normal y, offset d of n·x = d
    new = np.empty((4, 2))
    for _ in range(_ITERATIONS):
        cx = 0.25 * (corners[0, 0] + corners[1, 0] + corners[2, 0] + corners[3, 0])
        cy = 0.25 * (corners[0, 1] + corners[1, 1] + corners[2, 1] + corners[3, 1])
        for k in range(4):
            p0, p1 = corners[k], corners[(k + 1) % 4]
            length = math.hypot(p1[0] - p0[0], p1[1] - p0[1])
            scale = max(length, 1e-12)
            ox, oy = (p1[1] - p0[1]) / scale, -(p1[0] - p0[0]) / scale
            if ox * (0.5 * (p0[0] + p1[0]) - cx) + oy * (0.5 * (p0[1] + p1[1]) - cy) < 0:
                ox, oy = -ox, -oy
            # The border's width along this normal: the marker's extent across
            # the edge (the neighbouring edges projected on the normal) / modules.
            far0, far1 = corners[(k + 3) % 4], corners[(k + 2) % 4]
            depth = 0.5 * abs(
                ox * (far0[0] - p0[0]) + oy * (far0[1] - p0[1])
                + ox * (far1[0] - p1[0]) + oy * (far1[1] - p1[1])
            )  # fmt: skip
            reach = 0.8 * depth / modules
            if not _edge_line(gray, p0, p1, length, ox, oy, reach, lines[k], scratch):
                return False
        for k in range(4):
            # Corner k joins edge k−1 (from corner k−1) and edge k (to corner k+1).
            a, b = lines[k - 1], lines[k]
            det = a[0] * b[1] - a[1] * b[0]
            if abs(det) < 1e-6:
                return False
            new[k, 0] = (a[2] * b[1] - a[1] * b[2]) / det
            new[k, 1] = (a[0] * b[2] - a[2] * b[0]) / det
        shortest, moved = np.inf, 0.0
        for k in range(4):
            side = corners[k] - corners[k - 1]
            shortest = min(shortest, math.hypot(side[0], side[1]))
            moved = max(moved, math.hypot(new[k, 0] - corners[k, 0], new[k, 1] - corners[k, 1]))
        if moved > shortest / modules:
            return False
        corners[:] = new
    return True


@njit(cache=True, nogil=True)
def _edge_line(gray, p0, p1, length, ox, oy, reach_px, line, scratch):
    """Fit the edge p0→p1 (outward unit normal (ox, oy)) into ``line``; False if it fails.

    On each normal the profile f(s) ∈ [0, 1] (0 = black border, 1 = white
    plate) is integrated over [−R, R]; for a step at e blurred by any
    symmetric kernel (the pixel's box among them) ∫ f ds = R − e, so the
    edge lies at e = R − ∫ f ds whatever the sub-pixel phase of the edge.
    """
    n_normals = _n_normals(length)
    n_steps = _n_steps(reach_px)
    if n_normals > scratch.profile.shape[0] or n_steps > scratch.profile.shape[1]:
        return False  # past the scratch's bound (a non-finite quad): never a fitted edge
    t = _linspace(_SPAN[0], _SPAN[1], n_normals, scratch.t)
    offsets = _linspace(-reach_px, reach_px, n_steps, scratch.offsets)
    base, profile, points = scratch.base, scratch.profile, scratch.points
    rows, cols = gray.shape
    for i in range(n_normals):
        bx = base[i, 0] = p0[0] + t[i] * (p1[0] - p0[0])
        by = base[i, 1] = p0[1] + t[i] * (p1[1] - p0[1])
        # A normal whose ends lie inside the pixel grid lies inside it whole: its
        # samples need no clamping (the same values, a third fewer operations).
        x0, y0 = bx + offsets[0] * ox, by + offsets[0] * oy
        x1, y1 = bx + offsets[n_steps - 1] * ox, by + offsets[n_steps - 1] * oy
        inside = (
            min(x0, x1) >= 0.0 and max(x0, x1) < cols - 1.0
            and min(y0, y1) >= 0.0 and max(y0, y1) < rows - 1.0
        )  # fmt: skip
        for j in range(n_steps):
            x = bx + offsets[j] * ox
            y = by + offsets[j] * oy
            profile[i, j] = _interpolate(gray, x, y) if inside else _bilinear(gray, x, y)
    ends = max(1, n_steps // 6)
    # Levels per edge, from the ends of all its normals: less noisy than per normal.
    levels = scratch.levels
    for i in range(n_normals):
        for j in range(ends):
            levels[i * ends + j] = profile[i, j]
    dark = _median(levels, n_normals * ends)
    for i in range(n_normals):
        for j in range(ends):
            levels[i * ends + j] = profile[i, n_steps - ends + j]
    bright = _median(levels, n_normals * ends)
    if bright - dark <= 0.2 * max(abs(bright), abs(dark), 1e-12):
        return False
    n_clean = 0
    gain = 1.0 / (bright - dark)  # a product per sample, not a division
    for i in range(n_normals):
        # Normals crossing something other than one edge (a neighbour's module,
        # the sample) have a wrong end; keep those that start dark and end bright.
        clean = True
        for j in range(ends):
            clean &= (profile[i, j] - dark) * gain < 0.25
            clean &= (profile[i, n_steps - ends + j] - dark) * gain > 0.75
        if not clean:
            continue
        # The trapezoids of the normalised profile, taken as it is normalised.
        area = 0.0
        before = min(max((profile[i, 0] - dark) * gain, 0.0), 1.0)
        for j in range(1, n_steps):
            f = min(max((profile[i, j] - dark) * gain, 0.0), 1.0)
            area += (offsets[j] - offsets[j - 1]) * (f + before) / 2.0
            before = f
        e = reach_px - area
        points[n_clean, 0] = base[i, 0] + e * ox
        points[n_clean, 1] = base[i, 1] + e * oy
        n_clean += 1
    if n_clean < 3:
        return False
    # Total least squares: the line through the centroid along the points'
    # major axis; its normal is the scatter matrix's minor axis.
    mx, my = points[:n_clean, 0].mean(), points[:n_clean, 1].mean()
    sxx = sxy = syy = 0.0
    for i in range(n_clean):
        dx, dy = points[i, 0] - mx, points[i, 1] - my
        sxx += dx * dx
        sxy += dx * dy
        syy += dy * dy
    major = 0.5 * math.atan2(2.0 * sxy, sxx - syy)
    nx, ny = -math.sin(major), math.cos(major)
    line[0], line[1], line[2] = nx, ny, nx * mx + ny * my
    return True


@njit(cache=True, nogil=True)
def _scratch(n_normals, n_steps):
    """Scratch for edges of at most ``n_normals`` normals of ``n_steps`` samples."""
    return _ScratchArrays(
        np.empty(n_normals), np.empty(n_steps), np.empty((n_normals, 2)),
        np.empty((n_normals, n_steps)), np.empty((n_normals, 2)),
        np.empty(n_normals * n_steps),
    )  # fmt: skip


@njit(cache=True, nogil=True)
def _n_normals(length):
    """Normals across an edge ``length`` px long: one per pixel of its span."""
    return max(4, int(length * (_SPAN[1] - _SPAN[0])))


@njit(cache=True, nogil=True)
def _n_steps(reach_px):
    """Samples along a normal reaching ``reach_px`` either side: odd, ≥ 9."""
    return max(9, int(2 * reach_px * _STEPS_PER_PX) | 1)


@njit(cache=True, nogil=True)
def _median(values, n):
    """``np.median(values[:n])``, reordering ``values[:n]``: the middle value, or the mean
    of the two middle values for even n (numpy's arithmetic). ``np.median`` copied the
    levels twice and selected with a branch per comparison that the noisy levels
    mispredict half the time: a third of the edge fits."""
    k = n // 2
    upper = _select(values, n, k)
    if n % 2:
        return upper
    lower = values[0]  # after the selection values[:k] ≤ values[k]: the (k − 1)-th is their max
    for i in range(1, k):
        lower = max(lower, values[i])
    return (lower + upper) / 2


@njit(cache=True, nogil=True)
def _select(values, n, k):
    """The k-th smallest of ``values[:n]``, partitioning in place so that
    ``values[:k] ≤ values[k] ≤ values[k + 1:n]``: quickselect with Lomuto's partition
    made branch-free (every element swapped, the boundary advanced by the comparison),
    the pivot the median of three; equal values are grouped, so a flat run (a saturated
    plate) takes one pass."""
    lo, hi = 0, n - 1
    while lo < hi:
        mid = (lo + hi) // 2
        a, b, c = values[lo], values[mid], values[hi]
        pick = mid if (a <= b) == (b <= c) else (lo if (b <= a) == (a <= c) else hi)
        pivot = values[pick]
        values[pick], values[hi] = values[hi], pivot
        below = _partition(values, lo, hi, pivot, False)  # [lo, below) < pivot
        if k < below:
            hi = below - 1
            continue
        upto = _partition(values, below, hi, pivot, True)  # [below, upto) == pivot
        values[upto], values[hi] = values[hi], values[upto]
        if k <= upto:
            return pivot
        lo = upto + 1
    return values[k]


@njit(cache=True, nogil=True, inline="always")
def _partition(values, lo, hi, pivot, equal):
    """Move the values of ``values[lo:hi]`` that are < ``pivot`` (``equal``: ≤) to its
    front, branch-free; returns where they end."""
    store = lo
    for i in range(lo, hi):
        x = values[i]
        values[i] = values[store]
        values[store] = x
        store += (x <= pivot) if equal else (x < pivot)
    return store


@njit(cache=True, nogil=True)
def _linspace(start, stop, num, out):
    """``np.linspace(start, stop, num)`` in numpy's arithmetic (i · step + start), into
    ``out[:num]``, which it returns."""
    step = (stop - start) / (num - 1)
    for i in range(num):
        out[i] = i * step + start
    out[num - 1] = stop
    return out[:num]


@njit(cache=True, nogil=True)
def _bilinear(gray, x, y):
    """Bilinear grey level at column x, row y; outside, the nearest edge pixel's."""
    rows, cols = gray.shape
    x = min(max(x, 0.0), cols - 1.0)
    y = min(max(y, 0.0), rows - 1.0)
    c0 = min(int(x), cols - 2)
    r0 = min(int(y), rows - 2)
    return _blend(gray, r0, c0, x - c0, y - r0)


@njit(cache=True, nogil=True, inline="always")
def _interpolate(gray, x, y):
    """:func:`_bilinear` at 0 ≤ x < W − 1, 0 ≤ y < H − 1, where it needs no clamping."""
    c0, r0 = int(x), int(y)
    return _blend(gray, r0, c0, x - c0, y - r0)


@njit(cache=True, nogil=True, inline="always")
def _blend(gray, r0, c0, fx, fy):
    """The bilinear mix of pixels (r0, c0) … (r0 + 1, c0 + 1) at fractions fx, fy."""
    top = (1.0 - fx) * gray[r0, c0] + fx * gray[r0, c0 + 1]
    bottom = (1.0 - fx) * gray[r0 + 1, c0] + fx * gray[r0 + 1, c0 + 1]
    return (1.0 - fy) * top + fy * bottom
