"""The Wang rig (seed 001, the default kind): turntable, light arc with lamps and laser, camera arc.

Its sections sit at the top of the config (``rig.sections``); its kinematics
are ``rig.kinematics``, its compiler ``rig.schedule.compile_axes`` over the
turntable and arc, its motion model ``rig.timing.motion_s``.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from rig import kinematics
from rig.config import RigConfig
from rig.devices import DEVICE_ROLES
from rig.kinds import KINDS
from rig.parts import Lamp
from rig.plan import Plan
from rig.schedule import compile_axes
from rig.steps import Schedule, Step
from rig.timing import motion_s

__all__ = ["WANG", "WangRig"]


class WangRig:
    """Turntable and light arc move; every camera that needs a lamp fires at once."""

    name = "wang"
    section = None
    device_roles = DEVICE_ROLES
    lamps_on_arc = True

    def config_defaults(self, data: dict[str, Any]) -> dict[str, Any]:
        return data

    def check(self, config: RigConfig) -> None:
        return None

    def lamps(self, config: RigConfig) -> tuple[Lamp, ...]:
        return config.light_arc.lamps

    def device_section(self, config: RigConfig, role: str) -> Any:
        return getattr(config, role)

    def with_device_sections(self, config: RigConfig, sections: Mapping[str, Any]) -> RigConfig:
        return config.model_copy(update=dict(sections))

    def compile(self, plan: Plan, config: RigConfig) -> Schedule:
        return compile_axes(plan, config, inverse=kinematics.inverse, motion=self.motion_s)

    def motion_s(self, config: RigConfig, start, target):
        return motion_s(config, start, target)

    def step_directions(self, config: RigConfig, step: Step):
        views, light = {}, None
        for shot in step.shots:
            view, light = kinematics.forward(
                config, turntable_deg=step.pose.turntable_deg, arc_deg=step.pose.arc_deg,
                camera=shot.camera, lamp=step.source,
            )  # fmt: skip
            views[shot.camera] = (float(view[0]), float(view[1]))
        return views, (float(light[0]), float(light[1]))

    def inverse(self, config: RigConfig, view_deg, light_deg) -> kinematics.RigPose:
        return kinematics.inverse(config, view_deg, light_deg)

    def recorded_lamp_mm(
        self, config: RigConfig, lamp_id: str, actuators: Mapping[str, float]
    ) -> np.ndarray:
        """From the step's recorded ``arc_deg`` and ``turntable_deg``."""
        return kinematics.lamp_position_mm(
            config, lamp_id, arc_deg=actuators.get("arc_deg", 0.0),
            turntable_deg=actuators.get("turntable_deg", 0.0),
        )  # fmt: skip

    def displaced_by_deg(self, config: RigConfig, actuators: Mapping[str, float]) -> float:
        """0: a step records the directions its cameras and lamps stand at, the same for
        every pair that asked for them, so they are its sampling's."""
        return 0.0

    def posed_camera(self, config: RigConfig, camera_id: str, actuators: Mapping[str, float]):
        return None  # the holder's markers place every frame


WANG = KINDS.register("rig", "wang")(WangRig())
