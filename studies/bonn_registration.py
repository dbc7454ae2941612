"""Registration on the simulated Bonn lab against the simulator's truth (docs/btf.md).

The scene of ``studies/registration_views.py`` (flat Lambertian sample 0.01 mm
below the plate, smooth albedo, frames rendered with 3 × 3 area sampling) on the Bonn lab:
its one lamp directional. For each (view, light) pair the real drivers turn the plate with
the arm and move the camera along the rail against the simulated lab's peers; the camera
server's frame of the world state is registered with ``register_frame`` and compared with
``Simulator.btf_truth`` of the pair (ray cast) on the texel grid: mean marker reprojection,
corner error against the Bonn camera model's projection, texture RMSE.

``rig bench bonn-registration`` prints the table (one row per pair).
"""

from __future__ import annotations

import numpy as np

from drivers import open_device
from processing.registration import marker_corners_mm, register_frame
from rig import bonn
from rig.clock import VirtualClock
from rig.devices import Retry
from sim import scene_from_dict
from sim.rig import SimulatedRig
from sim.sensor import full_scale

__all__ = ["PAIRS", "SIZE", "bonn_scene", "measure", "run", "texture_rmse"]

SIZE = 64
PAIRS = (
    ((0.0, 0.0), (34.0, 90.0)),
    ((17.0, 60.0), (51.0, 200.0)),
    ((34.0, 150.0), (17.0, 0.0)),
    ((51.0, 300.0), (34.0, 30.0)),
    ((51.0, 20.0), (68.0, 180.0)),
    ((68.0, 90.0), (0.0, 0.0)),
)
_FAST = Retry(timeout_s=0.5, retries=2, backoff_s=0.01)


def bonn_scene(*, scale: float = 0.5, supersample: int = 3, lamp_kind: str = "directional"):
    albedo = {"kind": "noise", "rgb": [0.6, 0.5, 0.4], "variation": 0.3, "scale_mm": 8.0}
    return scene_from_dict({
        "name": "bonn-registration",
        "effects": [],
        "sample": {"generator": "flat", "depth_mm": 0.01, "materials": ["m"]},
        "materials": {"m": {"albedo": albedo}},
        "rig": {"kind": "bonn", "overrides": {"bonn": {"lamp_kind": lamp_kind}}},
        "render": {"scale": scale, "supersample": supersample},
    })  # fmt: skip


def measure(pairs=PAIRS, *, posed_rail_error_deg: float | None = None) -> list[dict]:
    """One row per pair: markers, reprojection, corner error, texture RMSE (relative).

    With ``posed_rail_error_deg`` the frames are registered with the posed camera model
    too (``register_frame(posed=…)``), its rail position off by that many degrees: where
    the markers give no valid homography, the pose does (``Reason.FROM_RIG_POSE``).
    """
    clock = VirtualClock()
    rows = []
    with SimulatedRig(bonn_scene(), clock=clock) as sim:
        config = sim.rig_config()
        arm_section = config.bonn.arm.model_copy(
            update={"device": config.bonn.arm.device.model_copy(update={"retry": _FAST})}
        )
        arm = open_device("arm", arm_section, clock=clock)
        rail = open_device("rail", config.bonn.rail, clock=clock)
        try:
            arm.home()
            rail.home()
            sim.world.set_lamp(config.bonn.lamp_id, True)
            for view, light in pairs:
                pose = bonn.inverse(config, view, light)
                arm.move_to(bonn.plate_tool_pose(config, pose.rotation))
                rail.move_to(pose.rail_deg)
                arm.wait_until_settled()
                rail.wait_until_settled()
                rows.append(_row(sim, config, view, light, pose, posed_rail_error_deg))
        finally:
            arm.close()
            rail.close()
    return rows


def _row(sim, config, view, light, pose, posed_rail_error_deg=None) -> dict:
    frame = sim.simulator.render("cam0", sim.world.snapshot())
    rotation = sim.world.snapshot().plate_rotation()  # where the arm really holds the plate
    rail_deg = sim.world.position("rail")
    camera = bonn.camera_model(sim.scene.rig, "cam0", rotation, rail_deg)
    posed = None
    if posed_rail_error_deg is not None:
        posed = bonn.camera_model(sim.scene.rig, "cam0", rotation, rail_deg + posed_rail_error_deg)
    result = register_frame(frame.image, config.holder, size=SIZE, camera=camera, posed=posed)
    plate = marker_corners_mm(config.holder)[result.detection.ids].reshape(-1, 2)
    projected, _ = camera.project(np.column_stack([plate, np.zeros(len(plate))]))
    corner = np.linalg.norm(result.detection.corners_px.reshape(-1, 2) - projected, axis=1)
    rmse = None
    if result.valid:
        rmse = texture_rmse(sim, config, result, rotation, rail_deg,
                            exposure_s=frame.exposure_s, bit_depth=frame.bit_depth)  # fmt: skip
    return {
        "view": view, "light": light, "rail_deg": pose.rail_deg,
        "tilt_deg": bonn.tilt_deg(config, pose.rotation), "markers": len(result.detection),
        "valid": bool(result.valid), "reason": result.reason,
        "reproj_px": result.homography.mean_reprojection_px,
        "corner_px": float(corner.mean()) if len(corner) else None,
        "rmse": rmse,
    }  # fmt: skip


def texture_rmse(sim, config, result, rotation, rail_deg, *, exposure_s, bit_depth) -> float:
    """RMSE of a registered frame's normtexture against ``btf_truth`` of the pair the plate
    ``rotation`` and the rail really made, relative to the truth's mean (texels inside the
    border ring, where the registration has them)."""
    view, light = bonn.forward(config, rotation, rail_deg)
    truth = _true_texture(sim, config, tuple(view), tuple(light), exposure_s, bit_depth)
    inner = (slice(1, -1), slice(1, -1))
    valid = result.normtexture.valid[inner]
    diff = result.normtexture.texture[inner][valid].astype(np.float64) - truth[inner][valid]
    return float(np.sqrt(np.mean(diff**2)) / truth[inner][valid].mean())


def _true_texture(sim, config, view, light, exposure_s, bit_depth, supersample: int = 4):
    """(N, N, 3) DN: texel averages of ``btf_truth`` × irradiance × the camera's DN scale."""
    n, s = SIZE, supersample
    texels = sim.simulator.btf_truth(view, light, n, rays=s).astype(np.float64)
    radiometry = sim.scene.spec.radiometry
    lab = config.bonn
    irradiance = radiometry.intensity_w_sr * lab.lamp_intensity / (lab.lamp_distance_mm / 1e3) ** 2
    dn = irradiance * exposure_s / radiometry.full_scale_exposure
    return texels * dn * full_scale(bit_depth)


def run(quick: bool = False) -> list[dict]:
    """The table of docs/btf.md: one row per pair (:data:`PAIRS`; ``quick``: the first
    three), the view and light (θ, φ degrees), rail and tilt (degrees), markers found,
    mean marker reprojection and corner error against the Bonn camera model (px) and
    the texture RMSE (% of the truth's mean)."""
    return [
        {
            "view": f"{r['view'][0]:.0f}°, {r['view'][1]:.0f}°",
            "light": f"{r['light'][0]:.0f}°, {r['light'][1]:.0f}°",
            "rail_deg": r["rail_deg"], "tilt_deg": r["tilt_deg"], "markers": r["markers"],
            "reproj_px": r["reproj_px"], "corner_px": r["corner_px"],
            "rmse_pct": None if r["rmse"] is None else 100 * r["rmse"],
        }
        for r in measure(PAIRS[:3] if quick else PAIRS)
    ]  # fmt: skip
