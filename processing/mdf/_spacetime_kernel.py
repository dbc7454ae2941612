"""The block fold of the space-time tracker, compiled (numba, cached on disk).

Per tile of pixels, frame by frame, SIMD over the pixels: the running
maximum, the running minimum, and a mark of the frame that last raised the
maximum. Then, per pixel of the tile, the window around a new maximum is
copied once ``r`` frames have followed it — only in tiles that raised a
maximum in this block or still wait for frames of an earlier one, as most
tiles of a sweep do neither. The frames are read where they lie: in the
caller's block, or in the tracker's ring (frames copied one at a time, and
the last 2r frames of a block, which later windows need), so nothing is moved
between blocks; a pixel's window is contiguous, ``(N, 2r+1)``, so taking it
touches one cache line, not 2r+1 (see ``docs/mdf.md``).
"""

from __future__ import annotations

import numpy as np
from numba import njit

#: Pixels per tile: the tile's running state stays in L1 while the block streams.
TILE = 4096
#: Frames per run of marks: a mark (1-based frame within the run) fits any
#: frame dtype, uint8 included.
_RUN = 255


@njit(cache=True, nogil=True)
def fold_block(ring, block, block_first, first, n_new, r, can_matter,
               best, low, index, held, window, waiting):  # fmt: skip
    """Fold frames ``first … first + n_new - 1`` into the running state.

    Frame f ≥ ``block_first`` is row ``f - block_first`` of ``block`` (B, N),
    an earlier one row ``f % rows`` of ``ring`` (rows, N); together they hold
    frames ``first - 2r … first + n_new - 1`` (a fold from the ring alone
    passes an empty block from ``first + n_new``). best, low : (N,) running
    maximum and minimum (the frames' dtype); index : (N,) int32 frame of the
    maximum (the earliest on ties; kept only for maxima ≥ can_matter, the
    others are never lit);
    held : (N,) int32 the frame whose surrounding samples ``window`` holds
    (-1: none); window : (N, 2r + 1) those samples; can_matter : the lowest
    maximum that can still be lit, in the frames' dtype; waiting : bool per
    tile of :data:`TILE` pixels, whether a window in it waits for frames.
    """
    size = best.shape[0]
    rows = ring.shape[0]
    last = first + n_new - 1
    kind = ring.dtype.type
    mark = np.empty(TILE, ring.dtype)
    need = np.empty(TILE, np.uint8)
    zero = kind(0)
    first_row = first % rows
    below = kind(can_matter - 1)  # ≥ can_matter is > below, for whole numbers and floats alike
    for tile in range(waiting.shape[0]):
        t0 = tile * TILE
        t1 = min(t0 + TILE, size)
        m = t1 - t0
        b = best[t0:t1]
        lo = low[t0:t1]
        at_tile = index[t0:t1]
        marks = mark[:m]
        raised = False
        for k0 in range(0, n_new, _RUN):
            marks[:] = 0
            for k in range(k0, min(k0 + _RUN, n_new)):
                f = first + k
                row = block[f - block_first, t0:t1] if f >= block_first else ring[f % rows, t0:t1]
                tag = kind(k - k0 + 1)
                # One loop of maxima and minima in the frames' dtype, so it
                # vectorises: a select between arrays, or a product with a
                # bool, does not (3-10× slower). Tags grow, so the mark is the
                # last frame that raised the maximum (a tie does not raise) to
                # where it can matter: a pixel that ends lit reached its
                # maximum that way, and raises in the dark (noise) mark nothing.
                for i in range(m):
                    sample, held_max = row[i], b[i]
                    marks[i] = max(marks[i], tag if sample > max(held_max, below) else zero)
                    b[i] = max(sample, held_max)
                    lo[i] = min(sample, lo[i])
            # Most tiles raise nothing in most blocks: one vector pass says so.
            top = zero
            for i in range(m):
                top = max(top, marks[i])
            if top == 0:
                continue
            raised = True
            base = np.int32(first + k0 - 1)
            for i in range(m):
                at_tile[i] = base + np.int32(marks[i]) if marks[i] > 0 else at_tile[i]
        if not (raised or waiting[tile]):
            continue
        # Pixels whose window is still to take, in a vector pass: noise raises
        # the maximum of dark pixels at random, a branch per pixel would stall.
        held_tile = held[t0:t1]
        pending = need[:m]
        count = 0
        for i in range(m):
            pending[i] = (held_tile[i] != at_tile[i]) & (b[i] >= can_matter)
            count += pending[i]
        wait = False
        for i in range(m if count else 0):
            if pending[i]:
                p = t0 + i
                at = at_tile[i]
                if at + r > last:
                    wait = True
                    continue
                if at - r >= block_first:  # all in the caller's block: most windows
                    for j in range(2 * r + 1):
                        window[p, j] = block[at - r - block_first + j, p]
                    held[p] = at
                    continue
                # Frames before the sequence start read as its first. The ring
                # row comes from that of the block's first frame (the window
                # lies within 2r frames before it or in the block): a division
                # per window was ~0.3 of a read slower.
                row = first_row + (max(at - r, 0) - first)
                row = row + rows if row < 0 else (row - rows if row >= rows else row)
                for j in range(2 * r + 1):
                    f = max(at - r + j, 0)
                    if f >= block_first:
                        window[p, j] = block[f - block_first, p]
                    else:
                        window[p, j] = ring[row, p]
                        if at - r + j >= 0:
                            row = row + 1 if row + 1 < rows else 0
                held[p] = at
        waiting[tile] = wait
