"""Scenes of the calibration targets on a rig, for ``rig calibrate … --sim``.

The target is the rig's own (``RigConfig.targets``); the effects are those a
calibration must cope with: sensor noise, lens distortion and vignetting.
"""

from __future__ import annotations

from typing import Literal

from rig.config import RigConfig
from sim.scene import Scene, scene_from_dict

__all__ = ["DEFAULT_DISTORTION", "TARGETS", "target_scene"]

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
    as_built: dict | None = None,
) -> Scene:
    """The simulated rig ``config`` with ``target``'s calibration part on the turntable.

    ``cameras``: the ChArUco wedge; ``laser``: the step block, with the laser;
    ``response``: the wedge again, seen through a camera with a tone curve
    (``response``, gamma 2.2) that saturates; ``lamps``: the chrome ball (black,
    a sharp Phong lobe); ``white``: the flat white target (in the recess, at
    ``targets.white.height_mm``).
    ``supersample`` anti-aliases the printed board (4: corners within ~0.05 px).
    Cameras with zero distortion get ``DEFAULT_DISTORTION``. ``as_built``: the
    scene's ``[as_built]`` table (``sim.as_built``), for a rig not built exactly to
    ``config``; the same table gives every target's scene the same deviations.
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
            "margin_mm": 0.0,  # a target's layout fills the measured square, wall to wall
            "params": {} if params is None else params.model_dump(mode="json"),
        },
        "materials": {"default": material},
        "rig": {"overrides": rig},
        "render": {"scale": scale, "supersample": supersample},
        "lens_distortion": {"coefficients": list(lens)},
        "as_built": dict(as_built or {}),
    }
    if target == "laser":
        data["laser"] = {"power_w": 0.1}  # the line near half of full scale at 5 ms
    return scene_from_dict(data, source=f"calibration target {target!r}")
