"""The block fold of the space-time tracker, compiled (numba, cached on disk).

Per tile of pixels, frame by frame, SIMD over the pixels: the running
maximum, the running minimum, and a mark of the frame that last raised the
maximum. Then, per pixel of the tile, the window around a new maximum is
copied once ``r`` frames have followed it. The numpy fold it replaced took a
max and a min reduction over the block, then gathered the block of every
raised pixel to find its frame (see ``docs/mdf.md``).
"""

from __future__ import annotations

import numpy as np
from numba import njit

#: Pixels per tile: the tile's running state stays in L1 while the block streams.
_TILE = 4096
#: Frames per run of marks: a mark (1-based frame within the run) fits any
#: frame dtype, uint8 included.
_RUN = 255


@njit(cache=True, nogil=True)
def fold_block(buffer, n_new, first, r, can_matter, best, low, index, snapped, window):
    """Fold buffer rows ``2r … 2r + n_new`` (frames ``first …``) into the running state.

    buffer : (2r + block, N) the last 2r folded frames, then the new ones;
    best, low : (N,) running maximum and minimum (the frames' dtype);
    index : (N,) int32 frame of the maximum (the earliest on ties);
    snapped : (N,) bool, whether ``window`` holds the samples around it;
    window : (2r + 1, N) those samples; can_matter : the lowest maximum
    that can still be lit (windows below it are not needed).
    """
    size = best.shape[0]
    last = first + n_new - 1
    kind = buffer.dtype.type
    mark = np.empty(_TILE, buffer.dtype)
    zero = kind(0)
    for t0 in range(0, size, _TILE):
        t1 = min(t0 + _TILE, size)
        m = t1 - t0
        b = best[t0:t1]
        lo = low[t0:t1]
        marks = mark[:m]
        for k0 in range(0, n_new, _RUN):
            marks[:] = 0
            for k in range(k0, min(k0 + _RUN, n_new)):
                row = buffer[2 * r + k, t0:t1]
                tag = kind(k - k0 + 1)
                # Three loops of their own, in the frames' dtype, each a max or
                # a min: a select between arrays, or a product with a bool,
                # does not vectorise (3-10× slower). Tags grow, so the mark is
                # the last frame that raised the maximum (a tie does not raise).
                for i in range(m):
                    marks[i] = max(marks[i], tag if row[i] > b[i] else zero)
                for i in range(m):
                    b[i] = max(row[i], b[i])
                for i in range(m):
                    lo[i] = min(row[i], lo[i])
            for i in range(m):
                if marks[i] > 0:
                    index[t0 + i] = first + k0 + np.int32(marks[i]) - 1
                    snapped[t0 + i] = False  # a new maximum: its window is still to take
        for i in range(m):
            p = t0 + i
            at = index[p]
            if snapped[p] or b[i] < can_matter or at + r > last:
                continue
            # buffer row of frame f: f - first + 2r (clamped at the sequence start)
            for j in range(2 * r + 1):
                window[j, p] = buffer[max(at - first + r + j, 0), p]
            snapped[p] = True
