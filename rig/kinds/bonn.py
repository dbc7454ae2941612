"""The Bonn lab (seed 000 §3.1): one fixed lamp, an arm turning the plate, a camera on a rail.

Its section is ``[bonn]`` (``rig.kind_sections.BonnLab``: lamp, rail, arm);
its kinematics are ``rig.bonn``, its compiler and motion model
``rig.bonn_plan`` (one step per pair, an ``ArmRailPose``). A step records the
rail position and the arm's tool pose, from which the camera is posed where a
frame's markers fail (registration) and the lamp placed over the sample.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from rig import bonn
from rig.bonn_plan import compile_bonn, motion_s
from rig.camera import PinholeCamera
from rig.config import RigConfig
from rig.devices import ARM_ROLE, RAIL_ROLE
from rig.kinds import KINDS
from rig.parts import Lamp
from rig.plan import Plan
from rig.steps import Schedule, Step

__all__ = ["BONN", "BonnRig"]


class BonnRig:
    """The arm and the rail place plate and camera for each pair; the lamp stays lit."""

    name = "bonn"
    section = "bonn"
    device_roles = (ARM_ROLE, RAIL_ROLE, "lamp_bank")
    lamps_on_arc = False  # the lamp stands still while the arm turns the plate under it

    def config_defaults(self, data: dict[str, Any]) -> dict[str, Any]:
        """One camera, on the rail, unless the config names its own."""
        if "camera_arc" in data:
            return data
        return {**data, "camera_arc": {"cameras": [{"id": "cam0", "theta_deg": 0.0}]}}

    def check(self, config: RigConfig) -> None:
        cameras = config.camera_arc.cameras
        if len(cameras) != 1:
            raise ValueError(
                f"camera_arc.cameras: the Bonn lab has one camera, on its rail; got "
                f"{[c.id for c in cameras]}"
            )

    def lamps(self, config: RigConfig) -> tuple[Lamp, ...]:
        return config.bonn.lamps()

    def device_section(self, config: RigConfig, role: str) -> Any:
        if role in (ARM_ROLE, RAIL_ROLE):
            return getattr(config.bonn, role)
        return getattr(config, role)

    def with_device_sections(self, config: RigConfig, sections: Mapping[str, Any]) -> RigConfig:
        """The arm's and the rail's sections go into ``[bonn]``, the others to the top."""
        top = dict(sections)
        lab = {role: top.pop(role) for role in (ARM_ROLE, RAIL_ROLE) if role in top}
        return config.model_copy(update={**top, "bonn": config.bonn.model_copy(update=lab)})

    def compile(self, plan: Plan, config: RigConfig) -> Schedule:
        return compile_bonn(plan, config)

    def motion_s(self, config: RigConfig, start, target):
        return motion_s(config, start, target)

    def step_directions(self, config: RigConfig, step: Step):
        """Where the arm's joints and the rail the step was sent to put camera and lamp."""
        rotation = bonn.plate_rotation(config, np.radians(step.pose.joints_deg))
        view, light = bonn.forward(config, rotation, step.pose.rail_deg)
        views = {camera: (float(view[0]), float(view[1])) for camera in step.cameras}
        return views, (float(light[0]), float(light[1]))

    def inverse(self, config: RigConfig, view_deg, light_deg) -> bonn.BonnPose:
        return bonn.inverse(config, view_deg, light_deg)

    def recorded_lamp_mm(
        self, config: RigConfig, lamp_id: str, actuators: Mapping[str, float]
    ) -> np.ndarray:
        return bonn.recorded_lamp_mm(config, lamp_id, actuators)

    def displaced_by_deg(self, config: RigConfig, actuators: Mapping[str, float]) -> float:
        return bonn.displaced_by_deg(config, actuators)

    def posed_camera(
        self, config: RigConfig, camera_id: str, actuators: Mapping[str, float]
    ) -> PinholeCamera:
        """The camera where the recorded rail position and tool pose put it."""
        return bonn.recorded_camera(config, camera_id, actuators)


BONN = KINDS.register("rig", "bonn")(BonnRig())
