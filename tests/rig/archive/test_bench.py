"""The append benchmark: a small pytest-benchmark case and the ``rig bench archive`` rows."""

import itertools

import numpy as np

from rig.archive import Archive, FrameFormat, StepRecord
from rig.archive.bench import TARGET_MB_S, frame_pool, run_bench


def test_target_rate_is_the_seed_laser_scan():
    assert abs(TARGET_MB_S - 141.56) < 0.01  # 8 cameras × 7.5 Hz × 1024×768×3 B


def test_append_step(benchmark, tmp_path):
    frames = frame_pool("texture", cameras=4, height=96, width=128)
    names = [f"cam{i}" for i in range(len(frames))]
    fmt = FrameFormat(96, 128, 3, "uint8")
    indices = itertools.count()
    with Archive.create(
        tmp_path / "a.zarr", plan={}, rig_config={}, cameras=dict.fromkeys(names, fmt)
    ) as archive:

        def append():
            step = StepRecord(
                index=next(indices), kind="mdf", cameras=tuple(names), exposures_s=(0.01,)
            )
            archive.append_step(step, {n: [f] for n, f in zip(names, frames, strict=True)})

        benchmark(append)
        n = len(archive.committed_steps())
        assert n >= 1
        np.testing.assert_array_equal(archive.read_frame(n - 1, "cam3"), frames[3])


def test_run_bench_rows(tmp_path):
    rows = run_bench(tmp_path, n_steps=2, repeats=1, cameras=2, height=32, width=48, workers=2)
    assert {r["name"] for r in rows} >= {"raw write (baseline)", "archive, zstd-1, 2 threads"}
    for row in rows:
        assert row["mb_s"] > 0
        # both are rounded in the row: equal to within the last digit
        assert abs(row["fraction_of_target"] - row["mb_s"] / TARGET_MB_S) <= 0.011
        if row["name"] == "raw write (baseline)":
            assert row["vs_raw"] == 1.0
    compression = {r["content"]: r["compression"] for r in rows if r["name"].startswith("archive")}
    assert compression["flat"] > compression["texture"] > 1.0 >= compression["noise"] - 0.01
    assert list(tmp_path.iterdir()) == []  # cleaned up
