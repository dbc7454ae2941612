"""Calibration sessions as plans: what the rig captures to calibrate each part.

A calibration is captured like any session — a plan the daemon runs into an
archive — so it can be resumed, replayed and re-computed later. The plans use
``[captures.fixed]`` shots at given turntable and arc angles: a camera
calibration is every camera at several turntable angles under one lamp. A
laser calibration is a laser scan of the step block from each mount, seen by
the zenith camera.
"""

from __future__ import annotations

import numpy as np
import tomli_w

from rig.config import RigConfig
from rig.errors import ConfigError

__all__ = [
    "BRACKET",
    "HIGHLIGHT",
    "camera_plan",
    "lamp_plan",
    "laser_plan",
    "response_plan",
    "turntable_angles",
    "white_plan",
]


HIGHLIGHT = 0.008  # the highlight's exposure, × the outline's: unclipped on chrome
BRACKET = (1 / 16, 1 / 8, 1 / 4, 1 / 2, 1.0, 2.0)  # exposure multipliers: 5 stops


def _camera(config: RigConfig, camera: str | None):
    """The camera named, or the one nearest the zenith."""
    if camera is not None:
        return config.camera(camera)
    return min(config.camera_arc.cameras, key=lambda c: abs(c.theta_deg))


def _zenith_lamp(config: RigConfig) -> str:
    return min(config.light_arc.lamps, key=lambda lamp: abs(lamp.theta_deg)).id


def _plan(name: str, description: str, captures: dict, archive: str, **exposure) -> str:
    plan = {
        "sample": {"name": f"calibration-{name}", "description": f"{description}, rig calibrate"},
        "captures": captures,
        "output": {"archive": archive},
    }
    if exposure:
        plan["exposure"] = exposure
    return tomli_w.dumps(plan)


def turntable_angles(poses: int) -> np.ndarray:
    """``poses`` turntable angles around a full turn, offset by half a step so no
    board edge lines up with the pixel grid (which biases corner positions)."""
    if poses < 3:
        raise ConfigError(f"poses: need ≥ 3 turntable angles to calibrate a camera, got {poses}")
    return (np.arange(poses) + 0.5) * 360.0 / poses


def camera_plan(
    config: RigConfig, *, poses: int = 12, cameras=None, archive: str, exposure_s: float = 0.05
) -> str:
    """Plan TOML: every camera (or those named) sees the ChArUco wedge at ``poses``
    turntable angles, lit by the lamp nearest the zenith with the arc at 0°."""
    ids = {} if cameras is None else {"cameras": [config.camera(c).id for c in cameras]}
    lamp = _zenith_lamp(config)
    fixed = [{"turntable_deg": float(a), "lamp": lamp, **ids} for a in turntable_angles(poses)]
    return _plan("cameras", "ChArUco wedge", {"fixed": fixed}, archive, exposure_s=exposure_s)


def laser_plan(
    config: RigConfig, *, archive: str, scan_step_deg: float = 0.1, camera: str | None = None
) -> str:
    """Plan TOML: the step block scanned from every laser mount (arc at 0°), seen by
    ``camera`` (default: the camera nearest the zenith)."""
    spec = _camera(config, camera)
    far_side = 180.0 if spec.theta_deg < 0 else 0.0
    view = [abs(spec.theta_deg), (config.camera_arc.azimuth_deg + far_side) % 360.0]
    locations = [[abs(t), 180.0 if t < 0 else 0.0] for t in config.laser.mount_theta_deg]
    mdf = {"views": [view], "laser_locations": locations, "scan_step_deg": scan_step_deg}
    return _plan("laser", "laser step block", {"mdf": mdf}, archive)


def response_plan(
    config: RigConfig,
    *,
    archive: str,
    camera: str | None = None,
    exposure_s: float = 0.05,
    bracket=BRACKET,
) -> str:
    """Plan TOML: an exposure bracket of the ChArUco wedge (black, white and every
    shade of their edges and the lamp's fall-off) from ``camera`` (default: the
    camera nearest the zenith), at two turntable angles."""
    spec, lamp = _camera(config, camera), _zenith_lamp(config)
    fixed = [{"turntable_deg": a, "lamp": lamp, "cameras": [spec.id]} for a in (15.0, 105.0)]
    return _plan("response", "HDR bracket", {"fixed": fixed}, archive, exposure_s=exposure_s,
                 hdr_brackets=[float(m) for m in bracket])  # fmt: skip


def lamp_plan(
    config: RigConfig,
    *,
    archive: str,
    cameras=None,
    turntables=(0.0, 90.0, 180.0, 270.0),
    exposure_s: float = 0.05,
) -> str:
    """Plan TOML: the mirror sphere under each lamp (arc at 0°) at ``turntables``
    angles — the sphere's places, the baseline for near lamps — from every camera
    (or those named), each shot twice: a long exposure that lights the plate
    round the ball (its outline), a short one for the highlight."""
    ids = {} if cameras is None else {"cameras": [config.camera(c).id for c in cameras]}
    fixed = [
        {"turntable_deg": float(a), "lamp": lamp.id, **ids}
        for lamp in config.light_arc.lamps
        for a in turntables
    ]
    return _plan("lamps", "mirror sphere", {"fixed": fixed}, archive, exposure_s=exposure_s,
                 hdr_brackets=[1.0, HIGHLIGHT])  # fmt: skip


def white_plan(
    config: RigConfig, *, archive: str, camera: str | None = None, exposure_s: float = 0.02
) -> str:
    """Plan TOML: the white target under each lamp (arc at 0°), from ``camera``
    (default: the camera nearest the zenith)."""
    spec = _camera(config, camera)
    fixed = [
        {"turntable_deg": 0.0, "lamp": lamp.id, "cameras": [spec.id]}
        for lamp in config.light_arc.lamps
    ]
    return _plan("white", "white target", {"fixed": fixed}, archive, exposure_s=exposure_s)
