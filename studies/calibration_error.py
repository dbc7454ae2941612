"""`rig bench calibration`: calibration accuracy against the simulator's truth.

It runs the simulator and the calibration code side by side, so it lives on
top of both.
"""

from __future__ import annotations

import time

import numpy as np

from calibration.cameras import CameraCalibrationError, calibrate_turntable_camera, detect_charuco
from calibration.laser import band_offsets, laser_plane_angle, strip_pixels
from calibration.plans import camera_plan, turntable_angles
from processing.mdf import profile_axis_for
from rig.config import default_rig_config
from rig.kinematics import laser_plane
from rig.plan import parse_plan
from rig.schedule import compile_plan
from sim.calibration import target_scene
from sim.simulator import Simulator

__all__ = ["run"]


def run(quick: bool = False) -> list[dict]:
    """``rig bench calibration``: error against the simulator's truth, and the
    capture time each costs on the rig, against the number of board poses (per
    camera) and of laser target heights.

    Rows ``cameras``: for the zenith and a 30° camera, the turntable angles
    used, reprojection RMS, focal-length error, camera-centre error, capture
    time of the session (all cameras) and fit time. Rows ``laser``: heights,
    angle error at tilt 0, residual, fitted uncertainty.
    """
    config = default_rig_config()
    rows = []
    most = 12 if quick else 24
    counts = (4, 6, 12) if quick else (4, 6, 12, 24)
    scene = target_scene("cameras", config)
    lamp = min(scene.rig.light_arc.lamps, key=lambda lamp: abs(lamp.theta_deg)).id
    board = scene.rig.targets.charuco
    with Simulator(scene) as sim:
        for camera_id in ("cam0",) if quick else ("cam0", "cam2"):
            angles = turntable_angles(most)
            frames = [sim.render_state(camera_id, turntable_deg=a, lamps_on=[lamp]) for a in angles]
            views = [detect_charuco(frame.image, board) for frame in frames]
            true = scene.rig.camera_model(camera_id)
            centre = -true.R.T @ true.t
            for n in counts:
                pick = np.arange(0, most, most // n)  # every (most/n)-th: spread around the turn
                plan = parse_plan(camera_plan(config, poses=n, archive="bench.zarr"))
                start = time.perf_counter()
                try:
                    cam = calibrate_turntable_camera(
                        [views[i] for i in pick], angles[pick], board, (true.width, true.height)
                    )
                except CameraCalibrationError as err:
                    rows.append({"row": "cameras", "camera": camera_id, "poses": n,
                                 "failed": str(err).split(":")[0]})  # fmt: skip
                    continue
                rows.append({
                    "row": "cameras", "camera": camera_id, "poses": n,
                    "images_kept": len(cam.per_image_rms_px), "rms_px": cam.rms_px,
                    "focal_error_pct": 100 * (cam.K[0, 0] / true.K[0, 0] - 1),
                    "centre_error_mm": float(np.linalg.norm(cam.centre_mm - centre)),
                    "capture_s": compile_plan(plan, config).estimate.total_s,
                    "fit_s": time.perf_counter() - start,
                })  # fmt: skip
    for heights in ((0.0, 10.0), (0.0, 5.0, 10.0), (0.0, 4.0, 8.0, 12.0, 16.0)):
        rig = config.model_copy(
            update={
                "targets": config.targets.model_copy(
                    update={
                        "laser": config.targets.laser.model_copy(update={"heights_mm": heights})
                    }
                )
            }
        )
        laser_scene = target_scene("laser", rig, supersample=1)
        with Simulator(laser_scene) as sim:
            frame = sim.render_state("cam0", laser=True, laser_tilt_deg=0.0, exposure_s=0.005)
        camera = laser_scene.rig.camera_model("cam0")
        pixels = strip_pixels(frame.image, profile_axis=profile_axis_for(camera, [0.0, 1.0]))
        h, offsets, _ = band_offsets(pixels, camera, laser_scene.rig.targets.laser,
                                     sample_mm=laser_scene.rig.holder.sample_mm)  # fmt: skip
        angle = laser_plane_angle(h, offsets)
        normal, _ = laser_plane(rig, arc_deg=0.0, mount=0, tilt_deg=0.0, turntable_deg=0.0)
        rows.append({
            "row": "laser", "heights": len(heights),
            "angle_error_deg": angle.angle_deg - float(np.degrees(np.arccos(normal[2]))),
            "residual_mm": angle.residual_mm, "angle_std_deg": angle.angle_std_deg,
        })  # fmt: skip
    return rows
