"""Space-time peak analysis: when did each pixel see the laser sheet?

Seed ``001_…`` section 3.2, after Curless and Levoy's space-time analysis: for
each pixel, search its temporal sequence for the brightest frame; if it rises
above a prescribed threshold the pixel saw a lit mesostructure point at that
time, otherwise the point was occluded (-1). The time is refined to a fraction
of a frame with a sub-pixel peak detector.

The tracker streams: it keeps a running maximum, its frame index, a running
minimum (the background: the contrast max - min is what is thresholded, so
bright albedo is not mistaken for laser light), a ring of the last ``2r+1``
frames and, per pixel, the ``2r+1`` samples around its maximum, snapshotted
from the ring once ``r`` frames have followed it. Memory is ``O((4r+4)·H·W)``
whatever the sequence length.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from processing.mdf._errors import MdfError
from processing.mdf._reason import Reason
from processing.mdf.peaks import PeakMethod, peak_offset, peak_radius

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
    """Streaming per-pixel peak tracker; feed frames in order with :meth:`update`.

    Parameters
    ----------
    shape : (H, W)
        Frame size.
    method : {"centroid", "gaussian", "blais_rioux"}
        Sub-frame peak detector.
    min_contrast : float
        A pixel whose peak does not rise this far above its darkest frame is
        UNLIT, in frame units.
    """

    def __init__(self, shape, *, method: PeakMethod = "gaussian", min_contrast: float):
        if len(shape) != 2 or min(shape) < 1:
            raise MdfError(f"SpaceTimeTracker: shape must be (H, W), got {shape}")
        if not min_contrast > 0:
            raise MdfError(f"min_contrast must be > 0 (frame units), got {min_contrast}")
        self.shape = (int(shape[0]), int(shape[1]))
        self.method = method
        self.min_contrast = float(min_contrast)
        self._r = peak_radius(method)
        self._dtype: np.dtype | None = None  # fixed by the first frame
        self._count = 0
        # Pixels whose maximum moved, per frame of the last r + 1.
        self._moved: list[np.ndarray] = []

    @property
    def frames(self) -> int:
        """Frames seen so far."""
        return self._count

    def _allocate(self, dtype: np.dtype) -> None:
        size = self.shape[0] * self.shape[1]
        span = 2 * self._r + 1
        self._dtype = dtype
        self._ring = np.zeros((span, size), dtype)
        self._window = np.zeros((span, size), dtype)
        self._best = np.zeros(size, dtype)
        self._low = np.zeros(size, dtype)
        self._index = np.zeros(size, np.int32)
        self._snapped = np.zeros(size, bool)

    def update(self, frame) -> None:
        """Add the next frame, (H, W) or (H, W, C), any numeric dtype.

        Integer frames up to 16 bits are tracked in their own dtype (a quarter
        or half of the memory traffic of float32); others in float32.
        """
        f = _native_intensity(frame)
        if f.shape != self.shape:
            raise MdfError(f"frame {self._count} has shape {f.shape}, the scan has {self.shape}")
        f = f.ravel()
        k, r = self._count, self._r
        span = 2 * r + 1
        if self._dtype is None:
            self._allocate(f.dtype)
            self._best[:] = f
            self._low[:] = f
        elif f.dtype != self._dtype:
            f = f.astype(self._dtype)
        self._ring[k % span] = f
        moved = np.flatnonzero(f > self._best)
        self._best[moved] = f[moved]
        self._index[moved] = k
        np.minimum(self._low, f, out=self._low)
        self._moved.append(moved)
        if len(self._moved) > r + 1:
            self._moved.pop(0)
        if k >= 2 * r:
            # Pixels whose maximum is now r frames old get their window.
            sel = self._moved[0]
            sel = sel[self._index[sel] == k - r]
            if sel.size:
                order = [(k - 2 * r + j) % span for j in range(span)]
                self._window[:, sel] = self._ring[np.ix_(order, sel)]
                self._snapped[sel] = True
        self._count += 1

    def result(self) -> PixelPeaks:
        """The peaks of the frames seen so far."""
        if self._count == 0:
            raise MdfError("SpaceTimeTracker.result: no frame was added")
        best = self._best.astype(np.float32)
        low = self._low.astype(np.float32)
        contrast = best - low
        lit = contrast >= self.min_contrast
        # A window is complete only if it was snapshotted for the final maximum.
        complete = self._snapped & (self._index >= self._r)
        complete &= self._index <= self._count - 1 - self._r
        window = self._window.astype(np.float32) - low
        offset, ok = peak_offset(window, method=self.method)
        reason = np.full(contrast.shape, Reason.OK, np.uint8)
        reason[~ok] = Reason.FIT_FAILED
        reason[~complete] = Reason.AT_SEQUENCE_EDGE
        reason[~lit] = Reason.UNLIT
        good = reason == Reason.OK
        time = np.where(good, self._index + offset, -1.0).astype(np.float32)
        h, w = self.shape
        return PixelPeaks(
            time=time.reshape(h, w),
            contrast=contrast.reshape(h, w),
            reason=reason.reshape(h, w),
            frames=self._count,
        )


def _native_intensity(frame) -> np.ndarray:
    f = np.asarray(frame)
    if f.ndim == 3:
        f = f.max(axis=2)
    if f.ndim != 2:
        raise MdfError(f"frame must be (H, W) or (H, W, C), got shape {np.shape(frame)}")
    if f.dtype in (np.uint8, np.uint16):
        return f
    # Non-finite samples (a broken float frame) count as dark.
    return np.nan_to_num(f.astype(np.float32), nan=0.0, posinf=0.0, neginf=0.0)


def space_time_peaks(
    frames: Iterable, *, method: PeakMethod = "gaussian", min_contrast: float
) -> PixelPeaks:
    """Space-time peaks of a sequence, streamed (frames may be a generator).

    Parameters
    ----------
    frames : iterable of (H, W) or (H, W, C) arrays
    method, min_contrast
        As :class:`SpaceTimeTracker`.

    Returns
    -------
    PixelPeaks
    """
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
