"""The append benchmark: a small pytest-benchmark case and the ``rig bench archive`` rows."""

import itertools

import numpy as np
import pytest

from rig.archive import Archive, FrameFormat, StepRecord
from rig.config import default_rig_config
from studies.archive_write import TARGET_MB_S, frame_pool, laser_scan_mb_s, run

# Sessions, subprocesses or benches: the full tier only (make test), not make quick.
pytestmark = pytest.mark.slow


def test_target_rate_is_the_seed_laser_scan():
    # seed 001: 8 cameras of 1024×768 RGB at 7.5 Hz while scanning = 141.56 MB/s
    assert laser_scan_mb_s(default_rig_config()) == pytest.approx(141.557760)
    assert round(TARGET_MB_S, 6) == 141.55776  # the target the bench rows are fractions of


def test_scan_rate_follows_the_cameras_and_the_frame_rate():
    config = default_rig_config()
    cameras = config.camera_arc.cameras
    grey = cameras[0].model_copy(update={"channels": 1, "width": 640, "height": 480})
    arc = config.camera_arc.model_copy(update={"cameras": [grey, *cameras[1:4]]})
    laser = config.laser.model_copy(update={"frame_rate_hz": 15.0})
    smaller = config.model_copy(update={"camera_arc": arc, "laser": laser})
    expected = (640 * 480 + 3 * 1024 * 768 * 3) * 15.0 / 1e6
    assert laser_scan_mb_s(smaller) == pytest.approx(expected)


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


def test_run_rows(tmp_path):
    rows = run(out_dir=tmp_path, n_steps=2, repeats=1, cameras=2, height=32, width=48, workers=2)
    assert {r["name"] for r in rows} >= {"raw write (baseline)", "archive, zstd-1, 2 threads"}
    for row in rows:
        # a rate rounded to 0.1 MB/s: a tiny write on a loaded machine may round to 0
        assert row["mb_s"] >= 0 and row["mb_s_min"] <= row["mb_s"] <= row["mb_s_max"]
        if row["name"] == "raw write (baseline)":
            assert row["vs_raw"] == 1.0
    compression = {r["content"]: r["compression"] for r in rows if r["name"].startswith("archive")}
    assert compression["flat"] > compression["texture"] > 1.0 >= compression["noise"] - 0.01
    assert list(tmp_path.iterdir()) == []  # cleaned up
