"""Small archives with known frames, for the recovery and repair tests."""

from pathlib import Path

import numpy as np

from rig.archive import Archive, FrameFormat, StepRecord

CAMERAS = {"cam0": FrameFormat(16, 24, 3, "uint8"), "cam1": FrameFormat(8, 8, 1, "float32")}
SUBS = 2


def frame(step: int, camera: str, sub: int) -> np.ndarray:
    """The frame ``sub`` of ``camera`` at ``step``: pseudo-random, fixed by its ids."""
    fmt = CAMERAS[camera]
    rng = np.random.default_rng([step, sorted(CAMERAS).index(camera), sub])
    return (rng.random(fmt.shape) * 200).astype(fmt.dtype)


def step_record(index: int) -> StepRecord:
    return StepRecord(
        index=index,
        kind="ps",
        cameras=tuple(CAMERAS),
        light_deg=(45.0, 30.0 * index),
        exposures_s=(0.01, 0.02),
        lamp=index % 3,
        started_at=1.7e9 + index,
    )


def step_frames(index: int) -> dict[str, list[np.ndarray]]:
    return {c: [frame(index, c, s) for s in range(SUBS)] for c in CAMERAS}


def build_session(path: Path, n_steps: int, *, calibration: dict | None = None) -> Path:
    """An archive of steps 0 … n_steps − 1, closed cleanly."""
    with Archive.create(
        path, plan={"name": "t"}, rig_config={}, cameras=CAMERAS, fsync=False
    ) as archive:
        for index in range(n_steps):
            archive.append_step(step_record(index), step_frames(index))
        if calibration is not None:
            archive.set_calibration(calibration)
    return path


def chunk_files(path: Path) -> dict[str, bytes]:
    """Every chunk file under ``path``'s frames/, relative path → bytes."""
    return {
        p.relative_to(path).as_posix(): p.read_bytes()
        for p in sorted((path / "frames").rglob("c.*"))
    }


def assert_frames(path: Path, steps) -> None:
    """The archive at ``path`` has exactly ``steps``, every frame bit-exact."""
    with Archive.open(path) as archive:
        assert archive.committed_steps() == tuple(steps)
        for record in archive.step_table():
            expected = step_record(record.index)
            assert record.light_deg == expected.light_deg
            assert record.lamp == expected.lamp
        n = 0
        for info, image in archive.iter_frames():
            np.testing.assert_array_equal(image, frame(info.step, info.camera, info.sub))
            n += 1
        assert n == len(steps) * len(CAMERAS) * SUBS
