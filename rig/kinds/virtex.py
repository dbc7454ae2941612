"""The VirTex stage (seed 004): one camera straight above the sample, a ring of fixed lamps.

Nothing moves: its sample frame is the stage's, the camera looks down the z
axis and lamp *i* sits at its ring azimuth (``rig.kind_sections.VirtexStage``);
every step's pose keeps both (absent) axes at 0. It captures photometric
stereo only, and refuses a wanted pair it would only approximate.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from rig.config import RigConfig, arc_direction
from rig.errors import KinematicsError, PlanError
from rig.geometry import angular_distance_deg, direction_angles, direction_vector
from rig.kinds import KINDS
from rig.kinematics import RigPose
from rig.parts import Lamp
from rig.plan import Plan
from rig.schedule import compile_axes
from rig.steps import Schedule, Step

__all__ = ["VIRTEX", "VirtexRig"]

# What a VirTex stage cannot capture, and why (it has one zenith camera, fixed lamps).
_NOT_ON_VIRTEX = {
    "btf": "its one camera looks straight down, so it sees one view direction",
    "mdf": "it has no laser unit",
    "fixed": "it has no turntable or arc to position",
}
# A VirTex stage realises a wanted direction only as closely as this (deg).
_TOLERANCE_DEG = 0.5
_ZENITH = np.array([0.0, 0.0, 1.0])


class VirtexRig:
    """A camera and a lamp ring that stand still; one step per lamp."""

    name = "virtex"
    section = "virtex"
    device_roles = ("lamp_bank",)
    lamps_on_arc = True  # a fixed ring: the "arc" at 0°, places known from the config

    def config_defaults(self, data: dict[str, Any]) -> dict[str, Any]:
        """One camera straight above the stage unless the config names its own."""
        if "camera_arc" in data:
            return data
        return {**data, "camera_arc": {"cameras": [{"id": "cam0", "theta_deg": 0.0}]}}

    def check(self, config: RigConfig) -> None:
        oblique = [c.id for c in config.camera_arc.cameras if c.theta_deg != 0.0]
        if oblique:
            raise ValueError(
                f"camera_arc.cameras {oblique}: a VirTex stage's camera looks straight "
                "down at the sample; set theta_deg = 0"
            )

    def lamps(self, config: RigConfig) -> tuple[Lamp, ...]:
        return config.virtex.lamps()

    def device_section(self, config: RigConfig, role: str) -> Any:
        return getattr(config, role)

    def with_device_sections(self, config: RigConfig, sections: Mapping[str, Any]) -> RigConfig:
        return config.model_copy(update=dict(sections))

    def compile(self, plan: Plan, config: RigConfig) -> Schedule:
        problems = [
            f"captures.{capture}: a VirTex stage captures photometric stereo only "
            f"(captures.ps): {why}; remove [captures.{capture}] or use a rig config "
            "of another kind"
            for capture, why in _NOT_ON_VIRTEX.items()
            if getattr(plan.captures, capture) is not None
        ]
        if problems:
            raise PlanError("plan vs rig config", problems)

        def check_pair(kind: str, view, light, pose: RigPose) -> None:
            _check_reached(config, kind, view, light, pose)

        return compile_axes(
            plan, config, inverse=_inverse, motion=self.motion_s, check_pair=check_pair
        )

    def motion_s(self, config: RigConfig, start, target):
        """Nothing moves, nothing settles: zeros shaped as the targets."""
        zero = np.zeros(np.broadcast(np.asarray(target[0]), np.asarray(target[1])).shape)
        return zero, zero

    def step_directions(self, config: RigConfig, step: Step):
        view = direction_angles(arc_direction(0.0, config.camera_arc.azimuth_deg))
        light = direction_angles(_lamp_direction(config, step.source))
        views = {shot.camera: (float(view[0]), float(view[1])) for shot in step.shots}
        return views, (float(light[0]), float(light[1]))

    def inverse(self, config: RigConfig, view_deg, light_deg) -> RigPose:
        return _inverse(config, view_deg, light_deg)

    def recorded_lamp_mm(
        self, config: RigConfig, lamp_id: str, actuators: Mapping[str, float]
    ) -> np.ndarray:
        """The lamp's fixed place on the ring (a step records no actuators)."""
        return config.virtex.radius_mm * _lamp_direction(config, lamp_id)

    def displaced_by_deg(self, config: RigConfig, actuators: Mapping[str, float]) -> float:
        return 0.0  # every step records its lamp's and its camera's fixed directions

    def posed_camera(self, config: RigConfig, camera_id: str, actuators: Mapping[str, float]):
        return None  # the holder's markers place every frame


def _lamp_direction(config: RigConfig, lamp_id: str) -> np.ndarray:
    """(3,) unit vector from the sample centre towards lamp ``lamp_id`` of the ring."""
    lamp = config.lamp(lamp_id)
    index = [lamp.id for lamp in config.lamps].index(lamp.id)
    return direction_vector(lamp.theta_deg, config.virtex.azimuth_deg(index))


def _inverse(config: RigConfig, view_deg, light_deg, *, sources: str = "lamps") -> RigPose:
    """The stage's camera and the lamp nearest ``light_deg``; nothing moves."""
    if sources != "lamps":
        raise KinematicsError("a VirTex stage has no laser; its sources are its lamps")
    lamps = config.lamps
    lamp_dirs = np.array([_lamp_direction(config, lamp.id) for lamp in lamps])
    light_err = angular_distance_deg(lamp_dirs, direction_vector(*light_deg))
    n = int(np.argmin(np.round(light_err, 6)))
    return RigPose(
        turntable_deg=0.0,
        arc_deg=0.0,
        camera=config.camera_arc.cameras[0].id,
        lamp=lamps[n].id,
        view_residual_deg=float(angular_distance_deg(_ZENITH, direction_vector(*view_deg))),
        light_residual_deg=float(light_err[n]),
    )


def _check_reached(config: RigConfig, kind: str, view, light, pose: RigPose) -> None:
    """Refuse a pair the stage would only approximate, naming it and what the stage has."""
    problems = []
    if pose.view_residual_deg > _TOLERANCE_DEG:
        problems.append(
            f"captures.{kind}.views: view {view} is {pose.view_residual_deg:.1f}° from the "
            "stage camera's view (0, 0); a VirTex stage sees the sample from above only"
        )
    if pose.light_residual_deg > _TOLERANCE_DEG:
        stage = config.virtex
        azimuths = ", ".join(f"{stage.azimuth_deg(i):g}" for i in range(stage.lamp_count))
        problems.append(
            f"captures.{kind}.lights: light {light} is {pose.light_residual_deg:.1f}° from the "
            f"nearest lamp ({pose.lamp}); the stage's lamps are at theta_deg "
            f"{stage.lamp_theta_deg:g}, phi_deg {azimuths}"
        )
    if problems:
        raise PlanError("plan vs rig config", problems)


VIRTEX = KINDS.register("rig", "virtex")(VirtexRig())
