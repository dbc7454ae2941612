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
from calibration.lamps import (
    LampCalibrationError,
    SphereShot,
    flat_fields,
    lamp_direction,
    lamp_intensities,
    lamp_position,
    sphere_ray,
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
from rig.calfile import CalibrationFile, CameraResult, LampResult, LaserResult
from rig.config import RigConfig
from rig.material import FlatFieldMaps, copy_flat_field

__all__ = [
    "FlatFieldMaps",
    "LampRun",
    "LaserFrame",
    "apply_calibration",
    "calibrate_cameras",
    "calibrate_lamps",
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


@dataclass(frozen=True)
class LampRun:
    """What a lamp calibration used and left out: per lamp the shots that gave a
    ray, and the reasons of those that did not."""

    rays: dict[str, int]
    skipped: dict[str, list[str]]
    flat_field: FlatFieldMaps | None = None


def calibrate_lamps(
    sphere_archive: str | Path, white_archive: str | Path | None = None
) -> tuple[dict[str, LampResult], LampRun, dict[str, str]]:
    """Lamp directions (distant lamps) or positions (near ones) from a mirror-sphere
    session, and relative intensities from a white-target session if given.

    Results are in the light arc's frame at arc 0°. The cameras are the sphere
    archive's calibrated ones where it has them. Returns the results, what was
    used, and the lamps that failed with the reason.
    """
    rays, skipped, failed, results = defaultdict(list), defaultdict(list), {}, {}
    with Archive.open(sphere_archive, mode="r") as archive:
        config = RigConfig.model_validate(archive.rig_config)
        sphere = config.targets.sphere
        for record in archive.step_table():
            if record.lamp is None or len(record.exposures_s) < 2:
                continue
            outline_sub = int(np.argmax(record.exposures_s))
            highlight_sub = int(np.argmin(record.exposures_s))
            turntable = record.actuators["turntable_deg"]
            for camera_id in record.cameras:
                shot = SphereShot(
                    lamp=str(record.lamp), camera_id=camera_id,
                    camera=frame_camera(archive, config, camera_id, 0.0),
                    image=archive.read_frame(record.index, camera_id, highlight_sub),
                    turntable_deg=turntable,
                    silhouette=archive.read_frame(record.index, camera_id, outline_sub),
                    frame=f"step {record.index}",
                )  # fmt: skip
                try:
                    rays[shot.lamp].append(
                        sphere_ray(shot, sphere, saturation_level=_full_scale(shot.image))
                    )
                except LampCalibrationError as err:
                    skipped[shot.lamp].append(str(err))
    for lamp in config.light_arc.lamps:
        mine = rays.get(lamp.id, [])
        try:
            if lamp.kind == "directional":
                found = lamp_direction(mine)
                results[lamp.id] = LampResult(
                    direction=found.direction.tolist(), residual=found.spread_deg,
                    observations=found.rays, clipped=found.clipped,
                )  # fmt: skip
            else:
                found = lamp_position(mine)
                results[lamp.id] = LampResult(
                    position_mm=found.position_mm.tolist(), residual=found.rms_distance_mm,
                    observations=found.rays, clipped=found.clipped,
                )  # fmt: skip
        except LampCalibrationError as err:
            failed[lamp.id] = f"{err} ({len(skipped.get(lamp.id, []))} shot(s) gave no ray)"
    maps = None
    if white_archive is not None:
        results, maps = _with_intensities(results, white_archive, failed)
    run = LampRun({k: len(v) for k, v in rays.items()}, dict(skipped), maps)
    return results, run, failed


def _with_intensities(results: dict, white_archive, failed: dict):
    """Add relative intensities, per kind (near lamps' radiant intensities and
    distant lamps' irradiances are not comparable); and each lamp's fall-off map."""
    with Archive.open(white_archive, mode="r") as archive:
        config = RigConfig.model_validate(archive.rig_config)
        images = {}
        for record in archive.step_table():
            if record.lamp in results:
                camera_id = record.cameras[0]
                images[str(record.lamp)] = archive.read_frame(record.index, camera_id, 0)
        if not images:
            failed["intensities"] = "the white-target session has no frame of a calibrated lamp"
            return results, None
        camera = frame_camera(archive, config, camera_id, 0.0)
    target_z = config.targets.white.height_mm
    for near in (True, False):
        ids = [k for k in images if (results[k].position_mm is not None) == near]
        if not ids:
            continue
        where = {"positions_mm": [results[k].position_mm for k in ids]} if near else {
            "directions": [results[k].direction for k in ids]}  # fmt: skip
        stack = [images[k] for k in ids]
        try:
            relative = lamp_intensities(
                camera, stack, saturation_level=_full_scale(stack[0]), target_z_mm=target_z,
                **where,
            )  # fmt: skip
        except LampCalibrationError as err:
            failed["intensities"] = str(err)
            continue
        for k, value in zip(ids, relative, strict=True):
            results[k] = results[k].model_copy(update={"intensity": float(value)})
    try:
        field = flat_fields([images[k] for k in images])
    except LampCalibrationError as err:
        failed["flat field"] = str(err)
        return results, None
    return results, FlatFieldMaps(camera_id, tuple(images), field.falloff)


def _full_scale(image) -> float:
    return float(np.iinfo(image.dtype).max) if image.dtype.kind == "u" else float(image.max())


def apply_calibration(calibration: CalibrationFile, path: str | Path, session: str | Path) -> int:
    """Store ``calibration`` (read from the file at ``path``) in a session archive
    recorded earlier, with the flat fields it names, for re-processing to use
    (``rig calibrate … --apply``); returns the archive's calibration version."""
    with Archive.open(session, mode="a") as recorded:
        version = recorded.set_calibration(calibration.model_dump(mode="json", exclude_none=True))
        if calibration.lamps_flat_field is not None:
            copy_flat_field(path, calibration.lamps_flat_field, recorded.path)
    return version
