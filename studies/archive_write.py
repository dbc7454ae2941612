"""Append throughput of the session archive, against plain writes in the same run.

The target is the laser-scan rate of the seed rig [1]_: 8 cameras × 7.5 Hz ×
1024×768×3 bytes ≈ 141.6 MB/s of raw pixels, sustained. Throughput is counted
in raw (uncompressed) frame bytes per second, including every ``fsync`` the
method does, so it compares directly with that camera data rate.

Frame content (``frame_pool``):

- ``texture``: a smooth woven-like pattern (sums of sines at three scales, 8-bit
  range about 20–235, different per camera) plus Gaussian read noise of σ = 2 DN;
  the realistic case.
- ``noise``: uniform random bytes, incompressible (lower bound for zstd's gain).
- ``flat``: one grey value (upper bound: zstd's best case).

References
----------
.. [1] Wang, Tong, Lin, Hu, Guo, Shum. "Capturing and rendering geometry
   details for BTF-mapped surfaces." The Visual Computer 21, 2005 (seed 001).
"""

from __future__ import annotations

import os
import shutil
import tempfile
import time
from collections.abc import Callable
from functools import partial
from pathlib import Path

import numpy as np

from rig.archive import Archive, FrameFormat, StepRecord
from rig.config import RigConfig, default_rig_config

__all__ = ["TARGET_MB_S", "frame_pool", "laser_scan_mb_s", "run"]


def laser_scan_mb_s(config: RigConfig) -> float:
    """Raw pixel rate (MB/s, 10⁶ bytes) of every camera of ``config`` at the laser-scan rate."""
    frame_bytes = sum(c.width * c.height * c.channels for c in config.camera_arc.cameras)
    return frame_bytes * config.laser.frame_rate_hz / 1e6


#: The default (seed) rig's laser scan: 8 cameras × 7.5 Hz × 1024×768×3 bytes.
TARGET_MB_S = laser_scan_mb_s(default_rig_config())


def frame_pool(content: str, *, cameras: int, height: int, width: int) -> list[np.ndarray]:
    """One ``(height, width, 3)`` uint8 frame per camera of the given ``content``."""
    rng = np.random.default_rng(1)
    if content == "noise":
        return [rng.integers(0, 256, (height, width, 3), dtype=np.uint8) for _ in range(cameras)]
    if content == "flat":
        return [np.full((height, width, 3), 128, np.uint8) for _ in range(cameras)]
    if content != "texture":
        raise ValueError(f"content {content!r}: expected 'texture', 'noise' or 'flat'")
    y, x = np.mgrid[0:height, 0:width].astype(np.float32)
    frames = []
    for camera in range(cameras):
        shift = 0.7 * camera
        weave = np.sin(x / 3.1 + shift) * np.sin(y / 2.9)  # yarn scale, a few pixels
        ribs = np.sin((x + 0.3 * y) / 17.0 + shift)  # rib scale
        shading = np.cos(x / 260.0) * np.cos(y / 190.0)  # illumination falloff
        base = 128 + 45 * weave + 30 * ribs + 25 * shading
        rgb = base[..., None] * np.array([0.95, 1.0, 0.85], np.float32)
        rgb += rng.normal(0.0, 2.0, rgb.shape).astype(np.float32)
        frames.append(np.clip(np.rint(rgb), 0, 255).astype(np.uint8))
    return frames


def _write_raw(directory: Path, *, frames: list[np.ndarray], n_steps: int, fsync: bool) -> None:
    # Baseline: the same bytes, one file per frame, no container, no compression.
    for step in range(n_steps):
        for camera, frame in enumerate(frames):
            fd = os.open(directory / f"{step}-{camera}.raw", os.O_WRONLY | os.O_CREAT, 0o644)
            try:
                os.write(fd, frame.data)
                if fsync:
                    os.fsync(fd)
            finally:
                os.close(fd)


def _write_zarr_api(directory: Path, *, frames: list[np.ndarray], n_steps: int, level: int) -> None:
    # What zarr's own pipeline does with one frame per chunk (no fsync: zarr has none).
    import zarr

    group = zarr.open_group(directory / "z.zarr", mode="w")
    compressors = zarr.codecs.ZstdCodec(level=level) if level else None
    arrays = [
        group.create_array(
            f"cam{c}",
            shape=(n_steps, *f.shape),
            chunks=(1, *f.shape),
            dtype="uint8",
            compressors=compressors,
        )
        for c, f in enumerate(frames)
    ]
    for step in range(n_steps):
        for array, frame in zip(arrays, frames, strict=True):
            array[step] = frame


def _write_archive(
    directory: Path,
    frames: list[np.ndarray],
    n_steps: int,
    *,
    fsync: bool,
    level: int,
    workers: int,
) -> int:
    names = [f"cam{c}" for c in range(len(frames))]
    fmt = FrameFormat(*frames[0].shape, dtype="uint8")
    with Archive.create(
        directory / "a.zarr",
        plan={"bench": True},
        rig_config={},
        cameras=dict.fromkeys(names, fmt),
        zstd_level=level,
        fsync=fsync,
        workers=workers,
    ) as archive:
        for step in range(n_steps):
            record = StepRecord(index=step, kind="mdf", cameras=tuple(names), exposures_s=(0.01,))
            archive.append_step(record, {n: [f] for n, f in zip(names, frames, strict=True)})
    return sum(p.stat().st_size for p in (directory / "a.zarr" / "frames").rglob("c.*"))


def _timed(out_dir: Path, write: Callable[[Path], int | None]) -> tuple[float, int | None]:
    directory = out_dir / "bench-archive"
    shutil.rmtree(directory, ignore_errors=True)
    directory.mkdir(parents=True)
    try:
        start = time.perf_counter()
        stored = write(directory)
        return time.perf_counter() - start, stored
    finally:
        shutil.rmtree(directory, ignore_errors=True)


def _cases(pools, n_steps: int, workers: int) -> list[tuple[str, str, bool, Callable]]:
    texture = pools["texture"]
    cases = [
        ("raw write (baseline)", "texture", fs, partial(_write_raw, frames=texture, fsync=fs))
        for fs in (True, False)
    ]
    for level in (0, 1):
        name = f"zarr API, {'zstd-1' if level else 'no compression'}"
        cases.append(
            (name, "texture", False, partial(_write_zarr_api, frames=texture, level=level))
        )
    archive_cases = [
        ("texture", True, 1, workers),
        ("noise", True, 1, workers),
        ("flat", True, 1, workers),
        ("texture", False, 1, workers),
        ("texture", True, 1, 1),
        ("texture", True, 3, workers),
    ]
    for content, fsync, level, n in archive_cases:
        name = f"archive, zstd-{level}, {n} thread{'s' if n > 1 else ''}"
        write = partial(_write_archive, frames=pools[content], fsync=fsync, level=level, workers=n)
        cases.append((name, content, fsync, write))
    return [(name, c, fs, partial(write, n_steps=n_steps)) for name, c, fs, write in cases]


def run(
    quick: bool = False,
    *,
    out_dir: str | os.PathLike | None = None,
    n_steps: int | None = None,
    repeats: int | None = None,
    cameras: int = 8,
    height: int = 768,
    width: int = 1024,
    workers: int | None = None,
) -> list[dict]:
    """Measure append throughput; one row per method and frame content.

    Every method writes ``n_steps`` steps of ``cameras`` frames; the methods
    take turns, ``repeats`` times, and each row reports the median run (disk
    speed on shared machines drifts, so interleaving keeps the comparison fair).
    ``quick``: 8 steps, once (else 32 steps, 3 times); ``out_dir``: where the writes
    go (a temporary folder by default).

    Each row: ``name``, ``content``, ``fsync``, ``mb_s`` (raw frame MB/s,
    median), ``mb_s_min`` / ``mb_s_max``, ``fraction_of_target`` (of
    ``TARGET_MB_S``), ``vs_raw`` (median ratio to the raw baseline with the same
    ``fsync`` setting in the same repetition) and ``compression`` (raw / stored
    bytes, archive rows). Everything written under ``out_dir`` is removed again.
    """
    n_steps = n_steps or (8 if quick else 32)
    repeats = repeats or (1 if quick else 3)
    if out_dir is None:
        with tempfile.TemporaryDirectory(prefix="rig-bench-") as tmp:
            return _rows(Path(tmp), n_steps, repeats, cameras, height, width, workers)
    return _rows(Path(out_dir), n_steps, repeats, cameras, height, width, workers)


def _rows(out_dir: Path, n_steps, repeats, cameras, height, width, workers) -> list[dict]:
    workers = workers or min(8, os.cpu_count() or 1)
    contents = ("texture", "noise", "flat")
    pools = {c: frame_pool(c, cameras=cameras, height=height, width=width) for c in contents}
    raw_bytes = n_steps * sum(f.nbytes for f in pools["texture"])
    cases = _cases(pools, n_steps, workers)
    speeds = np.zeros((repeats, len(cases)))
    stored = [None] * len(cases)
    for repeat in range(repeats):
        for i, (_, _, _, write) in enumerate(cases):
            seconds, stored[i] = _timed(out_dir, write)
            speeds[repeat, i] = raw_bytes / seconds / 1e6
    rows = []
    for i, (name, content, fsync, _) in enumerate(cases):
        baseline = next(j for j, c in enumerate(cases) if c[0].startswith("raw") and c[2] == fsync)
        mb_s = float(np.median(speeds[:, i]))
        rows.append(
            {
                "name": name,
                "content": content,
                "fsync": fsync,
                "mb_s": round(mb_s, 1),
                "mb_s_min": round(float(speeds[:, i].min()), 1),
                "mb_s_max": round(float(speeds[:, i].max()), 1),
                "fraction_of_target": round(mb_s / TARGET_MB_S, 2),
                "vs_raw": round(float(np.median(speeds[:, i] / speeds[:, baseline])), 2),
                "compression": round(raw_bytes / stored[i], 2) if stored[i] else None,
            }
        )
    return rows
