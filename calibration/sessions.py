"""Calibration from a recorded calibration session: archive in, results out.

Reads only the archive (frames, step table): replaying the session and
computing again gives the same numbers. The rig config in the archive names
the cameras and lamps; its nominal intrinsics and poses are never used.
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Callable
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from calibration.cameras import (
    CameraCalibrationError,
    TurntableCamera,
    calibrate_turntable_camera,
    detect_charuco,
)
from calibration.laser import (
    LaserAngle,
    LaserCalibrationError,
    band_offsets,
    laser_plane_angle,
    strip_pixels,
)
from calibration.response import ResponseCurve, ResponseError, calibrate_response
from processing.mdf import profile_axis_for
from processing.offline import frame_camera
from rig.archive import Archive
from rig.calfile import CameraResult, LaserResult
from rig.config import RigConfig

__all__ = [
    "LaserFrame",
    "calibrate_cameras",
    "calibrate_laser",
    "calibrate_responses",
    "camera_result",
]

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


@dataclass(frozen=True)
class LaserFrame:
    """One scan frame of the step block: the sheet's tilt and the fitted angle (or why not)."""

    mount: int
    tilt_deg: float
    angle: LaserAngle | None
    reason: str = ""


def calibrate_laser(archive_path: str | Path) -> tuple[dict[int, LaserResult], list[LaserFrame]]:
    """The laser sheet's angle to the reference plane per mount, from a
    ``rig calibrate laser`` session; the cameras are the archive's calibrated
    ones where it has them (``processing.offline.frame_camera``).

    Every frame whose strip crosses ≥ 2 bands gives an angle; a mount's result
    is the frame nearest tilt 0 (the sheet's rest position).
    """
    frames: list[LaserFrame] = []
    with Archive.open(archive_path, mode="r") as archive:
        config = RigConfig.model_validate(archive.rig_config)
        steps = config.targets.laser
        tilts = {e.payload["step"]: e.payload["tilts_deg"] for e in archive.events("scan")}
        for record in archive.step_table():
            if record.kind != "mdf":
                continue
            arc = record.actuators["arc_deg"]
            strip = [-np.sin(np.deg2rad(arc)), np.cos(np.deg2rad(arc))]
            for camera_id in record.cameras:
                camera = frame_camera(archive, config, camera_id, record.actuators["turntable_deg"])
                axis = profile_axis_for(camera, strip)
                for sub, tilt in enumerate(tilts[record.index]):
                    image = archive.read_frame(record.index, camera_id, sub)
                    try:
                        pixels = strip_pixels(image, profile_axis=axis)
                        heights, offsets, _ = band_offsets(
                            pixels, camera, steps, sample_mm=config.holder.sample_mm
                        )
                        angle = laser_plane_angle(heights, offsets)
                        frames.append(LaserFrame(int(record.laser), float(tilt), angle))
                    except LaserCalibrationError as err:
                        frames.append(LaserFrame(int(record.laser), float(tilt), None, str(err)))
    results = {}
    for mount in sorted({f.mount for f in frames}):
        good = [f for f in frames if f.mount == mount and f.angle is not None]
        if good:
            best = min(good, key=lambda f: abs(f.tilt_deg))
            a = best.angle
            results[mount] = LaserResult(
                angle_deg=a.angle_deg, angle_std_deg=a.angle_std_deg, residual_mm=a.residual_mm,
                heights=a.heights, tilt_deg=best.tilt_deg,
            )  # fmt: skip
    return results, frames


def calibrate_responses(archive_path: str | Path) -> tuple[dict[str, ResponseCurve], int, dict]:
    """Each camera's inverse response curve from a ``rig calibrate response``
    session (Debevec & Malik over all its brackets together), the exposures per
    bracket, and the cameras that failed with the reason."""
    curves, failed = {}, {}
    with Archive.open(archive_path, mode="r") as archive:
        brackets = defaultdict(list)  # camera → [(images, exposures)] per step
        for record in archive.step_table():
            if len(record.exposures_s) < 2:
                continue
            for camera_id in record.cameras:
                images = [archive.read_frame(record.index, camera_id, sub)
                          for sub in range(len(record.exposures_s))]  # fmt: skip
                brackets[camera_id].append((images, record.exposures_s))
    for camera_id, sets in sorted(brackets.items()):
        # One bracket's images side by side: Debevec samples all of them.
        images = [np.concatenate([imgs[k] for imgs, _ in sets], axis=1)
                  for k in range(len(sets[0][0]))]  # fmt: skip
        try:
            curves[camera_id] = calibrate_response(images, sets[0][1])
        except ResponseError as err:
            failed[camera_id] = str(err)
    if not brackets:
        failed["*"] = "the session holds no exposure bracket (steps with ≥ 2 exposures)"
        return curves, 0, failed
    exposures = len(next(iter(brackets.values()))[0][1])
    return curves, exposures, failed
