"""Space-time peak analysis: when did each pixel see the laser sheet?

Seed ``001_…`` section 3.2, after Curless and Levoy's space-time analysis: for
each pixel, search its temporal sequence for the brightest frame; if it rises
above a prescribed threshold the pixel saw a lit mesostructure point at that
time, otherwise the point was occluded (-1). The time is refined to a fraction
of a frame with a sub-pixel peak detector.

The tracker streams in blocks of frames: it copies each frame into a ring
of ``2r + block`` frames and folds a full block in at once — a running
maximum with its frame index, a running minimum (the background: the
contrast max - min is what is thresholded, so bright albedo is not mistaken
for laser light) and, per pixel, the ``2r+1`` samples around its maximum,
copied once ``r`` frames have followed it. Per frame that is a copy into the
ring plus its share of one compiled pass over the block
(:mod:`processing.mdf._spacetime_kernel`: running max, min and the frame that
raised the maximum, per tile of pixels). Frames that come as an array
(:meth:`SpaceTimeTracker.update_block`) are folded where they lie, and only
the last ``2r`` of them are copied into the ring: that saves the copy, a
read and a write of every frame. :meth:`SpaceTimeTracker.result` is
one compiled pass over the pixels (:mod:`processing.mdf._fit_kernel`).
Memory is ``O((4r+1+block)·H·W)`` whatever the sequence length.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from processing.mdf._errors import MdfError
from processing.mdf._fit_kernel import METHOD_CODES, fit_peaks, log_table
from processing.mdf._spacetime_kernel import TILE, fold_block
from processing.mdf.peaks import PeakMethod, peak_radius

__all__ = ["PixelPeaks", "SpaceTimeTracker", "space_time_peaks"]


@dataclass(frozen=True)
class PixelPeaks:
    """Per-pixel result of the space-time analysis of one scan.

    Attributes
    ----------
    time : (H, W) float32
        Frame index of peak intensity with fraction; -1 where not OK.
    contrast : (H, W) float32
        Peak minus darkest intensity, frame units.
    reason : (H, W) uint8
        :class:`Reason`: OK, UNLIT, AT_SEQUENCE_EDGE or FIT_FAILED.
    frames : int
        Frames in the sequence.
    """

    time: np.ndarray
    contrast: np.ndarray
    reason: np.ndarray
    frames: int


class SpaceTimeTracker:
    """Streaming per-pixel peak tracker; feed frames in order with :meth:`update`
    (one at a time) or :meth:`update_block` (an array of them), in any mix.

    Parameters
    ----------
    shape : (H, W)
        Frame size.
    method : {"centroid", "gaussian", "blais_rioux"}
        Sub-frame peak detector.
    min_contrast : float
        A pixel whose peak does not rise this far above its darkest frame is
        UNLIT, in frame units.
    block : int
        Frames buffered and folded in at once (memory ``block`` frames; the
        per-frame cost is lowest around 4–8 for 1024×768 frames: larger
        blocks fall out of the cache between the copy and the fold); an
        array given to :meth:`update_block` is folded this many frames at a
        time.
    """

    def __init__(
        self, shape, *, method: PeakMethod = "gaussian", min_contrast: float, block: int = 8
    ):
        if len(shape) != 2 or min(shape) < 1:
            raise MdfError(f"SpaceTimeTracker: shape must be (H, W), got {shape}")
        if not min_contrast > 0:
            raise MdfError(f"min_contrast must be > 0 (frame units), got {min_contrast}")
        if int(block) != block or block < 1:
            raise MdfError(f"block must be a whole number of frames ≥ 1, got {block!r}")
        self.shape = (int(shape[0]), int(shape[1]))
        self.method = method
        self.min_contrast = float(min_contrast)
        self._r = peak_radius(method)
        self._block = int(block)
        self._dtype: np.dtype | None = None  # fixed by the first frame
        self._count = 0  # frames added
        self._folded = 0  # frames folded into the running state

    @property
    def frames(self) -> int:
        """Frames seen so far."""
        return self._count

    def _allocate(self, dtype: np.dtype) -> None:
        size = self.shape[0] * self.shape[1]
        self._dtype = dtype
        # A ring: frame f in row f % rows, the last 2r frames folded and the block being filled.
        self._ring = np.zeros((2 * self._r + self._block, size), dtype)
        self._window = np.zeros((size, 2 * self._r + 1), dtype)
        self._best = np.full(size, _lowest(dtype), dtype)
        self._can_matter = _can_matter(dtype, self.min_contrast)
        self._low = np.full(size, _highest(dtype), dtype)
        self._index = np.zeros(size, np.int32)
        self._held = np.full(size, -1, np.int32)
        self._waiting = np.zeros(-(-size // TILE), bool)

    def update(self, frame) -> None:
        """Add the next frame, (H, W) or (H, W, C), any numeric dtype.

        Integer frames up to 16 bits are tracked in their own dtype (a quarter
        or half of the memory traffic of float32); others in float32. The
        frame is copied: the caller may reuse its buffer.
        """
        f = self._checked(_native_intensity(frame, ndim=2), self._count)
        self._ring[self._count % self._ring.shape[0]] = f.ravel()
        self._count += 1
        if self._count - self._folded == self._block:
            self._fold()

    def update_block(self, frames) -> None:
        """Add the next frames, (B, H, W) or (B, H, W, C), in order.

        The same as :meth:`update` for each frame, without copying the block:
        it is folded where it lies, and only the last ``2r`` frames (those the
        next frames' windows may need) are copied. The tracker keeps no
        reference to ``frames`` after the call.
        """
        f = _native_intensity(frames, ndim=3)
        if len(f) == 0:
            return
        self._checked(f[0], self._count)
        rows = np.ascontiguousarray(f).reshape(len(f), -1)
        self._fold()  # the frames buffered by update() come first
        start, n = self._count, rows.shape[0]
        for first in range(start, start + n, self._block):
            fold_block(
                self._ring, rows, start, first, min(self._block, start + n - first), self._r,
                self._can_matter, self._best, self._low, self._index, self._held, self._window,
                self._waiting,
            )  # fmt: skip
        self._count = self._folded = start + n
        # The next frames' windows reach back 2r frames; older ones are in the ring already.
        ring = self._ring.shape[0]
        for frame in range(max(start, self._count - 2 * self._r), self._count):
            self._ring[frame % ring] = rows[frame - start]

    def _checked(self, frame: np.ndarray, number: int) -> np.ndarray:
        # The frame's (H, W) intensity, after the first fixed the scan's dtype.
        if frame.shape != self.shape:
            raise MdfError(f"frame {number} has shape {frame.shape}, the scan has {self.shape}")
        if self._dtype is None:
            self._allocate(frame.dtype)
        elif frame.dtype != self._dtype:
            raise MdfError(
                f"frame {number} is {frame.dtype}, the scan's frames are {self._dtype}: "
                "feed one dtype per scan"
            )
        return frame

    def _fold(self) -> None:
        """Fold the buffered frames into the running maximum, minimum and windows."""
        first = self._folded
        if self._count == first:
            return
        fold_block(
            self._ring, self._ring[:0], self._count, first, self._count - first, self._r,
            self._can_matter, self._best, self._low, self._index, self._held, self._window,
            self._waiting,
        )  # fmt: skip
        self._folded = self._count

    def result(self) -> PixelPeaks:
        """The peaks of the frames seen so far."""
        if self._count == 0:
            raise MdfError("SpaceTimeTracker.result: no frame was added")
        self._fold()
        size = self._best.shape[0]
        time = np.empty(size, np.float32)
        contrast = np.empty(size, np.float32)
        reason = np.empty(size, np.uint8)
        fit_peaks(
            self._window, self._best, self._low, self._index, self._held, self._count,
            self._r, np.float32(self.min_contrast), METHOD_CODES[self.method],
            log_table(self._dtype), time, contrast, reason,
        )  # fmt: skip
        h, w = self.shape
        return PixelPeaks(
            time=time.reshape(h, w),
            contrast=contrast.reshape(h, w),
            reason=reason.reshape(h, w),
            frames=self._count,
        )


def _can_matter(dtype: np.dtype, min_contrast: float):
    # The lowest maximum that can be min_contrast above a darker sample, in the dtype.
    if not np.issubdtype(dtype, np.integer):
        return dtype.type(-np.inf)
    info = np.iinfo(dtype)
    return dtype.type(min(np.ceil(info.min + min_contrast), info.max))


def _lowest(dtype: np.dtype):
    return np.iinfo(dtype).min if np.issubdtype(dtype, np.integer) else -np.inf


def _highest(dtype: np.dtype):
    return np.iinfo(dtype).max if np.issubdtype(dtype, np.integer) else np.inf


def _native_intensity(frames, *, ndim: int) -> np.ndarray:
    # (…, H, W) intensity of frames with ndim axes, or one more for colour.
    f = np.asarray(frames)
    if f.ndim == ndim + 1:
        f = f.max(axis=-1)
    if f.ndim != ndim:
        what = "(H, W) or (H, W, C)" if ndim == 2 else "(B, H, W) or (B, H, W, C)"
        raise MdfError(f"frames must be {what}, got shape {np.shape(frames)}")
    if f.dtype in (np.uint8, np.uint16):
        return f
    # Non-finite samples (a broken float frame) count as dark.
    return np.nan_to_num(f.astype(np.float32), copy=False, nan=0.0, posinf=0.0, neginf=0.0)


def space_time_peaks(
    frames: Iterable, *, method: PeakMethod = "gaussian", min_contrast: float
) -> PixelPeaks:
    """Space-time peaks of a sequence, streamed (frames may be a generator).

    Parameters
    ----------
    frames : iterable of (H, W) or (H, W, C) arrays, or a (F, H, W) or (F, H, W, C) array
        An array is folded where it lies (:meth:`SpaceTimeTracker.update_block`).
    method, min_contrast
        As :class:`SpaceTimeTracker`.

    Returns
    -------
    PixelPeaks
    """
    if isinstance(frames, np.ndarray) and frames.ndim in (3, 4) and len(frames):
        tracker = SpaceTimeTracker(frames.shape[1:3], method=method, min_contrast=min_contrast)
        tracker.update_block(frames)
        return tracker.result()
    tracker = None
    for frame in frames:
        if tracker is None:
            tracker = SpaceTimeTracker(
                np.shape(frame)[:2], method=method, min_contrast=min_contrast
            )
        tracker.update(frame)
    if tracker is None:
        raise MdfError("space_time_peaks: the sequence has no frames")
    return tracker.result()
