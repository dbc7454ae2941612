"""Scenes of the calibration targets on a rig, for ``rig calibrate … --sim``.

The target is the rig's own (``RigConfig.targets``); the effects are those a
calibration must cope with: sensor noise, lens distortion and vignetting.
"""

from __future__ import annotations

from typing import Literal

from rig.config import RigConfig
from sim.scene import Scene, scene_from_dict

__all__ = ["DEFAULT_DISTORTION", "TARGETS", "run_bench", "target_scene"]

TARGETS = ("cameras", "laser", "response", "lamps", "white")
DEFAULT_DISTORTION = (-0.08, 0.05, 0.0004, -0.0003, 0.0)
_FRAME_TIMEOUT_S = 120.0
_CHROME = {  # black, with a Phong lobe a few pixels wide: sharper ones localise worse
    "albedo": {"kind": "constant", "rgb": [0.0, 0.0, 0.0]},
    "specular": {"model": "phong", "ks": 0.9, "exponent": 200.0},
}
_PAPER = {"albedo": {"kind": "constant", "rgb": [0.85, 0.85, 0.85]}}


def target_scene(
    target: Literal["cameras", "laser", "response", "lamps", "white"],
    config: RigConfig,
    *,
    scale: float = 0.5,
    supersample: int = 4,
) -> Scene:
    """The simulated rig ``config`` with ``target``'s calibration part on the turntable.

    ``cameras``: the ChArUco wedge; ``laser``: the step block, with the laser;
    ``response``: the wedge again, seen through a camera with a tone curve
    (``response``, gamma 2.2) that saturates; ``lamps``: the chrome ball (black,
    a sharp Phong lobe); ``white``: the flat white target (in the recess, at
    ``targets.white.height_mm``).
    ``supersample`` anti-aliases the printed board (4: corners within ~0.05 px).
    Cameras with zero distortion get ``DEFAULT_DISTORTION``.
    """
    if target not in TARGETS:
        raise ValueError(f"no simulated target for {target!r}; valid are {list(TARGETS)}")
    rig = config.model_dump(mode="json")
    lens = next((tuple(c.dist) for c in config.camera_arc.cameras if any(c.dist)), None)
    for camera in rig["camera_arc"]["cameras"]:
        if lens is None:
            camera["dist"] = list(DEFAULT_DISTORTION)
        # a supersampled frame takes seconds to render: wait for it
        camera["connection"]["retry"]["timeout_s"] = _FRAME_TIMEOUT_S
    lens = lens or DEFAULT_DISTORTION
    targets = config.targets
    white = {"albedo": {"kind": "constant", "rgb": [targets.white.reflectance] * 3}}
    # target → (generator, its params, material, extra effects, recess depth mm)
    generator, params, material, effects, depth = {
        "cameras": ("charuco_wedge", targets.charuco, _PAPER, [], 5.0),
        "laser": ("laser_steps", targets.laser, _PAPER, ["laser"], 5.0),
        "response": ("charuco_wedge", targets.charuco, _PAPER, ["saturation", "response"], 5.0),
        "lamps": ("mirror_sphere", targets.sphere, _CHROME, ["specular"], 5.0),
        "white": ("flat", None, white, [], -targets.white.height_mm),
    }[target]
    data = {
        "name": f"calibration-{target}",
        "effects": ["noise", "lens_distortion", "vignetting", *effects],
        "sample": {
            "generator": generator,
            "depth_mm": depth,
            "params": {} if params is None else params.model_dump(mode="json"),
        },
        "materials": {"default": material},
        "rig": {"overrides": rig},
        "render": {"scale": scale, "supersample": supersample},
        "lens_distortion": {"coefficients": list(lens)},
    }
    if target == "laser":
        data["laser"] = {"power_w": 0.1}  # the line near half of full scale at 5 ms
    return scene_from_dict(data, source=f"calibration target {target!r}")


def run_bench(*, quick: bool = False) -> list[dict]:
    """``rig bench calibration``: error against the simulator's truth, and the
    capture time each costs on the rig, against the number of board poses (per
    camera) and of laser target heights.

    Rows ``cameras``: for the zenith and a 30° camera, the turntable angles
    used, reprojection RMS, focal-length error, camera-centre error, capture
    time of the session (all cameras) and fit time. Rows ``laser``: heights,
    angle error at tilt 0, residual, fitted uncertainty.
    """
    import time

    import numpy as np

    from calibration.cameras import (
        CameraCalibrationError,
        calibrate_turntable_camera,
        detect_charuco,
    )
    from calibration.laser import band_offsets, laser_plane_angle, strip_pixels
    from calibration.plans import camera_plan, turntable_angles
    from processing.mdf import profile_axis_for
    from rig.config import default_rig_config
    from rig.kinematics import laser_plane
    from rig.plan import parse_plan
    from rig.schedule import compile_plan
    from sim.simulator import Simulator

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
        rig = config.model_copy(update={"targets": config.targets.model_copy(
            update={"laser": config.targets.laser.model_copy(update={"heights_mm": heights})})})
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
