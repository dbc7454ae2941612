"""``rig bench mdf``: what MDF accuracy costs in capture and compute time.

:func:`run` returns table rows (dicts) of four kinds:

``read``
    The floors: one pass over a 1024×768 uint8 sequence (a running
    ``np.maximum``, which reads every frame once), and ``argmax(axis=0)`` of
    the sequence stacked in memory, in frames/s.
``space_time``
    :class:`~processing.mdf.spacetime.SpaceTimeTracker` throughput on the same
    sequence per peak detector, fed one frame at a time (``update``) or as
    the stacked array (``update_block``, as :func:`space_time_peaks` does
    with an array), in frames/s, its time as a multiple of the read
    (``ratio_to_read``), split into the streaming updates
    (``streaming_ratio_to_read``, per frame) and the sub-frame fit of
    ``result()`` (``fit_ratio_to_read``, once per scan for every lit pixel,
    so it weighs less the longer the sequence), and its speed-up over the
    argmax; all timed interleaved, in thread CPU time, best of 3, at each
    sequence length.
``detector``
    Per peak detector: laser line error on a flat plate at full resolution
    (px, largest distance from the true strip over ±40 mm along it, median
    over frames) and line detection time per 1024×768 frame.
``accuracy``
    Median and 95th-percentile MDF error (reference-plane px and mm) and
    coverage against the number of laser locations (1, 5, 13, 26) and the scan
    step, with the capture time each costs on the default rig: per location
    sweep/step frames at the scan frame rate, plus the light-arc moves between
    locations.

The accuracy rows use the analytic ribbed sample of
:mod:`processing.mdf.synthetic` at a reduced image scale (see ``scale``).
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from processing.mdf.displacement import reference_footprint_mm
from processing.mdf.line import detect_laser_line
from processing.mdf.merge import merge_scans
from processing.mdf.peaks import PEAK_METHODS
from processing.mdf.reference import ReferenceRegion, profile_axis_for
from processing.mdf.scan import MdfSettings, reconstruct_scan
from processing.mdf.spacetime import SpaceTimeTracker
from processing.mdf.synthetic import (
    RibbedSample,
    render_scan,
    rig_scan,
    true_distance,
)
from rig.config import RigConfig, default_rig_config
from rig.geometry import texel_centers_mm

__all__ = ["capture_time_s", "run"]

LOCATION_COUNTS = (1, 5, 13, 26)
STEP_FACTORS = (0.25, 0.5, 1.0, 2.0)  # × the rig's sweep speed / frame rate


def capture_time_s(config: RigConfig, *, locations: int, step_deg: float) -> float:
    """Seconds to scan one view from ``locations`` laser locations on the rig.

    Each location sweeps ``laser.sweep_deg`` in steps of ``step_deg``, one
    frame per step at ``laser.frame_rate_hz``; between locations the light arc
    turns by 360°/locations and settles. All cameras record at once, so this
    is also the time for all views at one turntable position.
    """
    laser, arc = config.laser, config.light_arc.axis
    frames = int(np.floor(laser.sweep_deg / step_deg + 1e-9)) + 1
    moves = (locations - 1) * (float(arc.move_time_s(360.0 / locations)) + arc.settle_s)
    return locations * frames / laser.frame_rate_hz + moves


def run(
    quick: bool = False,
    *,
    camera_id: str = "cam2",
    scale: float = 0.25,
    texels: int = 64,
    sheet_sigma_mm: float = 0.8,
    throughput_frames=(120, 200),
    location_counts=LOCATION_COUNTS,
    step_factors=STEP_FACTORS,
    seed: int = 0,
) -> list[dict]:
    """Measure MDF accuracy and speed; see the module docstring for the rows.

    Parameters
    ----------
    quick : bool
        Small sizes for a smoke run (scale 0.125, 32 texels, 24 frames timed,
        locations (1, 5), steps (1×, 2×), detectors at 1/4 resolution).
    camera_id : str
        The view (a camera of the default rig).
    scale : float
        Image scale of the accuracy scenes (1 = the camera's full size).
    texels : int
        Side of the texel grid for the accuracy rows.
    sheet_sigma_mm : float
        Gaussian half-width of the laser sheet.
    throughput_frames : tuple of int
        Lengths of the 1024×768 sequences that are timed (a real scan has
        sweep/step + 1 frames per laser location: 91 at the default step,
        181–361 at the finer ones).
    """
    config = default_rig_config()
    if quick:
        scale, texels, throughput_frames = 0.125, 32, (24,)
        location_counts, step_factors = (1, 5), (1.0, 2.0)
    camera = config.camera_model(camera_id)
    rows = _throughput(camera.height, camera.width, throughput_frames, seed)
    detector_camera = camera.scaled(0.25) if quick else camera
    rows += _detectors(config, detector_camera, sheet_sigma_mm, seed, quick)
    rows += _accuracy(
        config, camera, scale, texels, sheet_sigma_mm, location_counts, step_factors, seed
    )
    return rows


def _best(fn: Callable[[], object], repeats: int = 3, clock=time.perf_counter) -> float:
    times = []
    for _ in range(repeats):
        start = clock()
        fn()
        times.append(clock() - start)
    return min(times)


def _stripe_sequence(height: int, width: int, n: int, seed: int) -> list[np.ndarray]:
    # A Gaussian stripe sweeping down the image over noise: every pixel peaks once.
    rng = np.random.default_rng(seed)
    rows = np.arange(height, dtype=np.float32)[:, None] + np.zeros((1, width), np.float32)
    centres = np.linspace(-10, height + 10, n)
    frames = []
    for c in centres:
        value = 10 + 200 * np.exp(-((rows - c) ** 2) / (2 * 3.0**2))
        value += rng.normal(0, 1.5, value.shape).astype(np.float32)
        frames.append(np.clip(value, 0, 255).astype(np.uint8))
    return frames


def _throughput(height: int, width: int, lengths, seed: int) -> list[dict]:
    rows = []
    for n in lengths:
        rows += _throughput_of(_stripe_sequence(height, width, n, seed))
    return rows


def _throughput_of(frames: list[np.ndarray]) -> list[dict]:
    n = len(frames)
    height, width = frames[0].shape
    stacked = np.stack(frames)

    def read() -> None:
        acc = np.zeros_like(frames[0])
        for f in frames:
            np.maximum(acc, f, out=acc)

    # The streaming part (per frame) and the sub-frame fit (once per scan, every
    # lit pixel: all of them here) timed apart, so the per-frame cost is compared
    # with the per-frame floor and the fixed cost is shown as what it is.
    feeds = {
        "one at a time": lambda tracker: [tracker.update(f) for f in frames],
        "stacked": lambda tracker: tracker.update_block(stacked),
    }
    split = {(m, feed): [np.inf, np.inf] for m in PEAK_METHODS for feed in feeds}

    def track(method, feed) -> None:
        tracker = SpaceTimeTracker((height, width), method=method, min_contrast=20.0)
        start = time.thread_time()
        feeds[feed](tracker)
        middle = time.thread_time()
        tracker.result()
        end = time.thread_time()
        split[method, feed][0] = min(split[method, feed][0], middle - start)
        split[method, feed][1] = min(split[method, feed][1], end - middle)

    # Interleaved, best of 3, in thread CPU time: drifting load hits the floors
    # and the trackers alike, and time spent preempted does not count.
    calls = {
        "read": read,
        "argmax": lambda: stacked.argmax(axis=0),
        **{key: lambda key=key: track(*key) for key in split},
    }
    seconds = dict.fromkeys(calls, np.inf)
    for _ in range(3):
        for name, call in calls.items():
            seconds[name] = min(seconds[name], _best(call, repeats=1, clock=time.thread_time))
    rows = [
        {
            "kind": "read",
            "name": f"running max, {n} frames {width}×{height} uint8",
            "frames": n,
            "frames_per_s": n / seconds["read"],
        },
        {
            "kind": "read",
            "name": f"argmax(axis=0) of the {n} frames stacked",
            "frames": n,
            "frames_per_s": n / seconds["argmax"],
        },
    ]
    for method, feed in split:
        streaming, fit = split[method, feed]
        rows.append(
            {
                "kind": "space_time",
                "name": f"{method}, {n} frames {feed}",
                "frames": n,
                "frames_per_s": n / seconds[method, feed],
                "ratio_to_read": seconds[method, feed] / seconds["read"],
                "streaming_ratio_to_read": streaming / seconds["read"],
                "fit_ratio_to_read": fit / seconds["read"],
                "speedup_vs_argmax": seconds["argmax"] / seconds[method, feed],
            }
        )
    return rows


def _detectors(config, camera, sheet_sigma_mm, seed, quick) -> list[dict]:
    flat = RibbedSample(base_mm=0.0, rib_amplitude_mm=0.0, bumps=())
    holder = config.holder
    region = ReferenceRegion.from_holder(
        camera, sample_mm=holder.sample_mm, plate_mm=holder.plate_mm
    )
    scan = rig_scan(config, arc_deg=150.0, step_deg=1.0, sweep_deg=4.0 if quick else 8.0)
    frames = list(render_scan(camera, flat, scan, sheet_sigma_mm=sheet_sigma_mm, seed=seed))
    strip = np.array([-scan.source_mm[1], scan.source_mm[0]])
    axis = profile_axis_for(camera, strip)
    # Sample points on the plate where the true line lies, to measure its error.
    rows = []
    for method in PEAK_METHODS:
        errors = []
        for frame, n, c in zip(frames, scan.normal, scan.offset, strict=True):
            line = detect_laser_line(
                frame, region, profile_axis=axis, threshold=40.0, method=method, seed=seed
            )
            if line.valid:
                errors.append(_line_error_px(line, n, c, region))
        seconds = _best(
            lambda method=method: [
                detect_laser_line(f, region, profile_axis=axis, threshold=40.0, method=method)
                for f in frames
            ],
            repeats=1 if quick else 3,
        )
        rows.append(
            {
                "kind": "detector",
                "name": method,
                "line_error_px": float(np.median(errors)) if errors else -1.0,
                "line_ms_per_frame": 1e3 * seconds / len(frames),
            }
        )
    return rows


def _line_error_px(line, normal, offset, region) -> float:
    # Distance of the detected line from the true strip (n_xy · p = c on z = 0),
    # at points ±40 mm along it around the point nearest the origin, in pixels.
    m = np.asarray(normal[:2]) / np.linalg.norm(normal[:2])
    base = m * offset / np.linalg.norm(normal[:2])
    along = np.array([-m[1], m[0]])
    pts = base + np.linspace(-40, 40, 9)[:, None] * along
    return float(np.max(np.abs(pts @ line.normal - line.rho_mm)) / region.footprint_mm)


def _accuracy(
    config, camera, scale, texels, sheet_sigma_mm, location_counts, step_factors, seed
) -> list[dict]:
    cam = camera.scaled(scale)
    sample = RibbedSample(sample_mm=config.holder.sample_mm, plate_mm=config.holder.plate_mm)
    region = ReferenceRegion.from_holder(
        cam, sample_mm=config.holder.sample_mm, plate_mm=config.holder.plate_mm
    )
    grid = texel_centers_mm(config.holder.sample_mm, texels)
    truth = true_distance(cam, sample, grid)
    footprint = reference_footprint_mm(cam, grid)
    base_step = config.laser.sweep_speed_deg_s / config.laser.frame_rate_hz
    arcs = sorted({(90.0 + 360.0 * k / n) % 360 for n in location_counts for k in range(n)})
    rows = []
    for factor in step_factors:
        step = base_step * factor
        per_arc = {}
        for arc in arcs:
            scan = rig_scan(config, arc_deg=arc, step_deg=step)
            frames = render_scan(cam, sample, scan, sheet_sigma_mm=sheet_sigma_mm, seed=seed)
            per_arc[arc] = reconstruct_scan(
                frames,
                region,
                grid,
                source_mm=scan.source_mm,
                sheet_angle_deg=scan.angle_deg,
                settings=MdfSettings(),
            )
        for n in location_counts:
            chosen = [per_arc[(90.0 + 360.0 * k / n) % 360] for k in range(n)]
            merged = merge_scans(chosen)
            seen = merged.distance >= 0
            err_mm = np.abs(merged.distance - truth)[seen]
            err_px = err_mm / footprint[seen]
            rows.append(
                {
                    "kind": "accuracy",
                    "name": f"{n} locations, step {step:.3f}°",
                    "locations": n,
                    "step_deg": step,
                    "median_error_px": float(np.median(err_px)) if seen.any() else -1.0,
                    "p95_error_px": float(np.percentile(err_px, 95)) if seen.any() else -1.0,
                    "median_error_mm": float(np.median(err_mm)) if seen.any() else -1.0,
                    "coverage": float(seen.mean()),
                    "capture_time_s": capture_time_s(config, locations=n, step_deg=step),
                }
            )
    return rows
