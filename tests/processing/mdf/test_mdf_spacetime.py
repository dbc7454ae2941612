"""Streaming space-time peaks against a batch computation and known peak times."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from processing.mdf import (
    PEAK_METHODS,
    MdfError,
    Reason,
    SpaceTimeTracker,
    peak_offset,
    peak_radius,
    space_time_peaks,
)
from processing.mdf._fit_kernel import METHOD_CODES, fit_peaks, log_table
from tests.budgets import scaled


def sweep(centres, n_frames, *, sigma=1.2, peak=180.0, ambient=12.0, noise=0.0, seed=0):
    """Frames where pixel p peaks at frame centres[p] (a Gaussian in time)."""
    rng = np.random.default_rng(seed)
    t = np.arange(n_frames, dtype=np.float64)[:, None, None]
    value = ambient + peak * np.exp(-((t - centres[None]) ** 2) / (2 * sigma**2))
    value = value + rng.normal(0, noise, value.shape) if noise else value
    return np.clip(np.rint(value), 0, 255).astype(np.uint8)


@pytest.mark.parametrize("method", PEAK_METHODS)
def test_sub_frame_peak_times(method):
    centres = np.random.default_rng(3).uniform(5, 34, (12, 16))
    stack = sweep(centres, 40, noise=0.5)
    peaks = space_time_peaks(iter(stack), method=method, min_contrast=20.0)
    assert peaks.time.dtype == np.float32 and peaks.reason.dtype == np.uint8
    assert np.all(peaks.reason == Reason.OK)
    tol = {"gaussian": 0.03, "blais_rioux": 0.05, "centroid": 0.08}[method]
    assert np.median(np.abs(peaks.time - centres)) < tol


@scaled(0.5)
@given(
    seed=st.integers(0, 2**31),
    n_frames=st.integers(1, 30),
    method=st.sampled_from(PEAK_METHODS),
    dtype=st.sampled_from([np.uint8, np.uint16, np.float32]),
)
def test_streaming_equals_batch(seed, n_frames, method, dtype):
    rng = np.random.default_rng(seed)
    stack = (rng.random((n_frames, 5, 7)) * 200).astype(dtype)
    stack[rng.random(stack.shape) < 0.5] = 0  # ties and flat runs
    tracker = SpaceTimeTracker((5, 7), method=method, min_contrast=15.0)
    for frame in stack:
        tracker.update(frame)
    assert_batch_peaks(tracker.result(), stack, method, 15.0)


def assert_batch_peaks(got, stack, method, min_contrast):
    """``got`` equals a batch computation: first maximum, its window, background = minimum."""
    n_frames = len(stack)
    f = stack.astype(np.float64)
    k = f.argmax(axis=0)
    r = peak_radius(method)
    low = f.min(axis=0)
    contrast = f.max(axis=0) - low
    complete = (k >= r) & (k <= n_frames - 1 - r)
    idx = np.clip(k[None] + np.arange(-r, r + 1)[:, None, None], 0, n_frames - 1)
    window = np.take_along_axis(f, idx, axis=0) - low
    off, ok = peak_offset(window, method=method)
    lit = contrast >= min_contrast
    expect = np.where(lit, Reason.OK, Reason.UNLIT)
    expect = np.where(lit & ~complete, Reason.AT_SEQUENCE_EDGE, expect)
    expect = np.where(lit & complete & ~ok, Reason.FIT_FAILED, expect)
    np.testing.assert_array_equal(got.reason, expect)
    good = expect == Reason.OK
    np.testing.assert_allclose(got.time[good], (k + off)[good], atol=1e-4)
    assert np.all(got.time[~good] == -1)
    np.testing.assert_allclose(got.contrast, contrast, atol=1e-3)


@pytest.mark.parametrize("method", PEAK_METHODS)
@pytest.mark.parametrize("block", [1, 3, 8])
def test_many_tiles_of_pixels_equal_batch(method, block):
    # Over 3 tiles of the fold (4096 pixels each): the first peaks at frame 7
    # everywhere, so its windows wait for frames of a block that raises
    # nothing there; the others at random times, some at the sequence edges.
    rng = np.random.default_rng(block)
    centres = rng.uniform(-1, 26, (40, 256))
    centres[:16] = 7.0
    stack = sweep(centres, 26, noise=3.0, seed=block)
    tracker = SpaceTimeTracker((40, 256), method=method, min_contrast=20.0, block=block)
    for frame in stack:
        tracker.update(frame)
    got = tracker.result()
    assert {Reason.OK, Reason.AT_SEQUENCE_EDGE} <= set(got.reason.ravel().tolist())
    assert_batch_peaks(got, stack, method, 20.0)


def test_unlit_and_sequence_edge_pixels_are_flagged():
    centres = np.array([[10.0, 0.2, 19.0, 1e6]])  # middle, first frame, last frame, never
    stack = sweep(centres, 20)
    peaks = space_time_peaks(stack, min_contrast=20.0)
    assert peaks.reason.tolist() == [
        [Reason.OK, Reason.AT_SEQUENCE_EDGE, Reason.AT_SEQUENCE_EDGE, Reason.UNLIT]
    ]
    assert peaks.time[0, 1:].tolist() == [-1, -1, -1]
    assert peaks.frames == 20


def test_bright_albedo_without_laser_is_not_lit():
    stack = np.full((15, 2, 2), 240, np.uint8)
    stack[:, 0, 0] += np.arange(15, dtype=np.uint8) % 3  # flicker, no peak
    peaks = space_time_peaks(stack, min_contrast=20.0)
    assert np.all(peaks.reason == Reason.UNLIT)


def test_colour_and_non_finite_frames():
    centres = np.full((3, 4), 8.0)
    grey = sweep(centres, 16)
    colour = np.stack([grey // 4, grey, grey // 2], axis=-1)
    a = space_time_peaks(grey, min_contrast=20.0)
    b = space_time_peaks(colour, min_contrast=20.0)
    np.testing.assert_array_equal(a.time, b.time)
    broken = grey.astype(np.float32)
    broken[3, 0, 0] = np.nan
    broken[4, 1, 1] = np.inf
    c = space_time_peaks(broken, min_contrast=20.0)
    assert np.all(np.isfinite(c.time)) and np.all(np.isfinite(c.contrast))


def test_bad_inputs():
    with pytest.raises(MdfError, match="min_contrast"):
        SpaceTimeTracker((4, 4), min_contrast=0)
    with pytest.raises(MdfError, match="block"):
        SpaceTimeTracker((4, 4), min_contrast=1, block=0)
    tracker = SpaceTimeTracker((4, 4), min_contrast=1)
    with pytest.raises(MdfError, match="no frame"):
        tracker.result()
    with pytest.raises(MdfError, match="shape"):
        tracker.update(np.zeros((5, 4)))
    with pytest.raises(MdfError, match="no frames"):
        space_time_peaks([], min_contrast=1)


@scaled(1 / 3)
@given(seed=st.integers(0, 2**31), block=st.integers(1, 9), pause=st.integers(1, 24))
def test_block_size_and_a_result_midway_change_nothing(seed, block, pause):
    centres = np.random.default_rng(seed).uniform(2, 22, (6, 5))
    stack = sweep(centres, 25, noise=2.0, seed=seed)
    reference = space_time_peaks(stack, min_contrast=20.0)
    tracker = SpaceTimeTracker((6, 5), min_contrast=20.0, block=block)
    for k, frame in enumerate(stack):
        tracker.update(frame)
        if k + 1 == pause:
            tracker.result()
    got = tracker.result()
    np.testing.assert_array_equal(got.reason, reference.reason)
    np.testing.assert_array_equal(got.time, reference.time)
    np.testing.assert_array_equal(got.contrast, reference.contrast)


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16, np.float32])
@pytest.mark.parametrize("method", PEAK_METHODS)
def test_compiled_fit_equals_the_numpy_detectors(method, dtype):
    # Windows as the fold leaves them: ties with the maximum, dark samples at
    # the background, flat windows, peaks at the first and last frame, windows
    # never taken; compared with peak_offset pixel by pixel.
    rng = np.random.default_rng(7)
    r, n, frames = peak_radius(method), 4000, 30
    window = rng.integers(0, 200, (2 * r + 1, n)).astype(dtype)
    window[rng.random(window.shape) < 0.3] = 0
    window[r] = window.max(axis=0)
    tie = rng.random(n) < 0.2
    window[r - 1, tie] = window[r, tie]
    window[:, 300:350] = window[r, 300:350]  # flat
    low = np.minimum(window.min(axis=0), rng.integers(0, 3, n).astype(dtype))
    low[300:325] = 0  # flat, high above the background
    best = window[r].copy()
    index = rng.integers(0, frames, n).astype(np.int32)
    index[:100], index[100:200] = 0, frames - 1
    held = np.where(rng.random(n) < 0.95, index, -1).astype(np.int32)
    time = np.empty(n, np.float32)
    contrast = np.empty(n, np.float32)
    reason = np.empty(n, np.uint8)
    fit_peaks(np.ascontiguousarray(window.T), best, low, index, held, frames, r, np.float32(15.0),
              METHOD_CODES[method], log_table(np.dtype(dtype)), time, contrast, reason)  # fmt: skip

    expect_contrast = best.astype(np.float32) - low.astype(np.float32)
    lit = expect_contrast >= 15
    complete = (held == index) & (index >= r) & (index <= frames - 1 - r)
    off, ok = peak_offset(window.astype(np.float64) - low.astype(np.float32), method=method)
    expect = np.where(lit, np.where(complete, np.where(ok, Reason.OK, Reason.FIT_FAILED),
                                    Reason.AT_SEQUENCE_EDGE), Reason.UNLIT)  # fmt: skip
    assert {Reason.OK, Reason.FIT_FAILED, Reason.AT_SEQUENCE_EDGE, Reason.UNLIT} <= set(expect)
    np.testing.assert_array_equal(reason, expect)
    np.testing.assert_array_equal(contrast, expect_contrast)
    good = expect == Reason.OK
    np.testing.assert_array_equal(time[good], (index + off).astype(np.float32)[good])
    assert np.all(time[~good] == -1)


def feed_blocks(tracker, stack, sizes):
    """Feed ``stack`` in blocks of ``sizes`` (cycled) through a reused buffer
    that is overwritten after each call, as a caller reading chunks would."""
    buffer = np.empty_like(stack)
    start, k = 0, 0
    while start < len(stack):
        part = stack[start : start + sizes[k % len(sizes)]]
        chunk = buffer[: len(part)]
        chunk[:] = part
        tracker.update_block(chunk)
        buffer[:] = 255  # brighter than any frame: the tracker must hold no reference
        start, k = start + len(part), k + 1
    return tracker.result()


def frame_by_frame(stack, method, block=8):
    tracker = SpaceTimeTracker(stack.shape[1:3], method=method, min_contrast=20.0, block=block)
    for frame in stack:
        tracker.update(frame)
    return tracker.result()


def assert_same_peaks(got, expect):
    np.testing.assert_array_equal(got.reason, expect.reason)
    np.testing.assert_array_equal(got.time, expect.time)
    np.testing.assert_array_equal(got.contrast, expect.contrast)
    assert got.frames == expect.frames


@pytest.mark.parametrize("method", PEAK_METHODS)
@pytest.mark.parametrize("size", [1, 3, 8])
@pytest.mark.parametrize("n_frames", [1, 7, 25, 31])
def test_blocks_equal_frames_with_peaks_at_block_and_sequence_edges(method, size, n_frames):
    # Peaks on every frame, so some sit on the first and last frame of a
    # block (the caller's and the tracker's, 8) and of the sequence.
    centres = np.tile(np.arange(-1.0, n_frames + 1), (3, 1))
    centres[1] += 0.4
    centres[2] -= 0.3
    stack = sweep(centres, n_frames, noise=2.0, seed=n_frames)
    tracker = SpaceTimeTracker(centres.shape, method=method, min_contrast=20.0)
    got = feed_blocks(tracker, stack, [size])
    assert_same_peaks(got, frame_by_frame(stack, method))
    assert_batch_peaks(got, stack, method, 20.0)
    if n_frames > 2 * peak_radius(method):
        assert {Reason.OK, Reason.AT_SEQUENCE_EDGE} <= set(got.reason.ravel().tolist())


@scaled(0.5)
@given(
    seed=st.integers(0, 2**31),
    n_frames=st.integers(1, 40),
    method=st.sampled_from(PEAK_METHODS),
    dtype=st.sampled_from([np.uint8, np.uint16, np.float32]),
    block=st.integers(1, 9),
    sizes=st.lists(st.integers(1, 12), min_size=1, max_size=4),
)
def test_blocks_of_any_size_equal_frame_by_frame(seed, n_frames, method, dtype, block, sizes):
    rng = np.random.default_rng(seed)
    stack = (rng.random((n_frames, 5, 7)) * 200).astype(dtype)
    stack[rng.random(stack.shape) < 0.5] = 0  # ties and flat runs
    tracker = SpaceTimeTracker((5, 7), method=method, min_contrast=15.0, block=block)
    got = feed_blocks(tracker, stack, sizes)
    expect = SpaceTimeTracker((5, 7), method=method, min_contrast=15.0, block=block)
    for frame in stack:
        expect.update(frame)
    assert_same_peaks(got, expect.result())


@pytest.mark.parametrize("method", PEAK_METHODS)
def test_blocks_and_single_frames_mixed_over_many_tiles(method):
    # Over 3 tiles of the fold: frames one at a time, then blocks, then one at
    # a time again, with a result midway; the same as frame by frame.
    rng = np.random.default_rng(5)
    centres = rng.uniform(-1, 40, (40, 256))
    centres[:16] = 9.0  # windows that wait across the switch
    stack = sweep(centres, 41, noise=3.0, seed=5)
    tracker = SpaceTimeTracker((40, 256), method=method, min_contrast=20.0, block=4)
    for frame in stack[:6]:
        tracker.update(frame)
    tracker.update_block(stack[6:10])
    tracker.result()
    tracker.update_block(stack[10:11])
    tracker.update_block(stack[11:30])
    for frame in stack[30:33]:
        tracker.update(frame)
    tracker.update_block(stack[33:])
    assert_same_peaks(tracker.result(), frame_by_frame(stack, method, block=4))


def test_a_stacked_sequence_is_folded_as_a_block():
    centres = np.random.default_rng(2).uniform(0, 20, (6, 9))
    grey = sweep(centres, 21, noise=1.0)
    colour = np.stack([grey // 4, grey, grey // 2], axis=-1)
    expect = frame_by_frame(grey, "gaussian")
    assert_same_peaks(space_time_peaks(grey, min_contrast=20.0), expect)
    assert_same_peaks(space_time_peaks(colour, min_contrast=20.0), expect)
    strided = np.zeros((21, 6, 18), np.uint8)
    strided[:, :, ::2] = grey
    assert_same_peaks(space_time_peaks(strided[:, :, ::2], min_contrast=20.0), expect)
    floats = space_time_peaks(grey.astype(np.float64), min_contrast=20.0)
    np.testing.assert_array_equal(floats.reason, expect.reason)


def test_block_inputs_are_checked():
    tracker = SpaceTimeTracker((4, 4), min_contrast=1)
    tracker.update_block(np.zeros((0, 4, 4), np.uint8))
    assert tracker.frames == 0
    with pytest.raises(MdfError, match="shape"):
        tracker.update_block(np.zeros((2, 5, 4), np.uint8))
    with pytest.raises(MdfError, match=r"\(B, H, W\)"):
        tracker.update_block(np.zeros((4, 4), np.uint8))
    tracker.update_block(np.zeros((2, 4, 4), np.uint8))
    with pytest.raises(MdfError, match="uint16"):
        tracker.update(np.zeros((4, 4), np.uint16))
    assert tracker.frames == 2
