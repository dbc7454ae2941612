"""Calibration from a recorded calibration session: archive in, results out.

Reads only the archive (frames, step table): replaying the session and
computing again gives the same numbers. The rig config in the archive names
the cameras and lamps; its nominal intrinsics and poses are never used.
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Callable
from contextlib import contextmanager
from pathlib import Path

import cv2

from calibration.cameras import (
    CameraCalibrationError,
    TurntableCamera,
    calibrate_turntable_camera,
    detect_charuco,
)
from rig.archive import Archive
from rig.calfile import CameraResult
from rig.config import RigConfig

__all__ = ["calibrate_cameras", "camera_result"]

Progress = Callable[[str], None]


def calibrate_cameras(
    archive_path: str | Path, *, progress: Progress | None = None
) -> tuple[dict[str, TurntableCamera], dict[str, str]]:
    """Each camera's calibration from a ``rig calibrate cameras`` session.

    Returns the calibrated cameras and, for cameras that could not be
    calibrated, the reason (the others still are).
    """
    cameras, failed = {}, {}
    with Archive.open(archive_path, mode="r") as archive, _one_cv_thread():
        config = RigConfig.model_validate(archive.rig_config)
        board = config.targets.charuco
        turntable = {s.index: s.actuators.get("turntable_deg", 0.0) for s in archive.step_table()}
        found, sizes = defaultdict(list), {}
        for info, image in archive.iter_frames():
            found[info.camera].append((info.step, info.sub, detect_charuco(image, board)))
            sizes[info.camera] = (image.shape[1], image.shape[0])
        for camera_id in sorted(found):
            # in step order, whatever order the frames were committed in (a replay's may differ)
            frames = sorted(found[camera_id], key=lambda f: f[:2])
            try:
                cameras[camera_id] = calibrate_turntable_camera(
                    [view for _, _, view in frames], [turntable[step] for step, _, _ in frames],
                    board, sizes[camera_id],
                )  # fmt: skip
            except CameraCalibrationError as err:
                failed[camera_id] = str(err)
            if progress is not None:
                done = cameras.get(camera_id)
                progress(f"{camera_id}: " + (f"RMS {done.rms_px:.3f} px" if done else "failed"))
    return cameras, failed


@contextmanager
def _one_cv_thread():
    """OpenCV's parallel loops add up in varying order, which moves the fit in the
    sixth digit; one thread makes a recomputation (or a replay's) reproduce the
    numbers to the bit."""
    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        yield
    finally:
        cv2.setNumThreads(threads)


def camera_result(camera: TurntableCamera) -> CameraResult:
    """The calibration-file record of a calibrated camera."""
    return CameraResult(
        K=camera.K.tolist(), dist=camera.dist.tolist(), R=camera.R.tolist(),
        t=camera.t.ravel().tolist(), image_size=camera.image_size, rms_px=camera.rms_px,
        images=len(camera.per_image_rms_px),
        per_image_rms_px={str(i): e for i, e in camera.per_image_rms_px.items()},
        rejected={str(i): why for i, why in camera.rejected.items()},
        axis_tilt_deg=camera.axis_tilt_deg,
    )  # fmt: skip
