"""Each rig kind's kinematics module, looked up by the config's ``kind``.

``rig.kinematics`` serves the Wang rig and the VirTex stage, ``rig.bonn`` the
Bonn lab. Each answers the same questions about a recorded step, with the
same signatures (:class:`StepKinematics`), so the processing stages ask the
rig's kind and never test it by name.
"""

from __future__ import annotations

from collections.abc import Mapping
from types import ModuleType
from typing import Protocol, cast

import numpy as np

from rig import bonn, kinematics
from rig.config import RigConfig

__all__ = ["StepKinematics", "step_kinematics"]


class StepKinematics(Protocol):
    """What a kind's module answers about a step from its recorded ``actuators``."""

    #: Whether the lamps ride a light arc (their place follows from arc and turntable).
    LAMPS_ON_ARC: bool

    def recorded_lamp_mm(
        self, config: RigConfig, lamp_id: str, actuators: Mapping[str, float]
    ) -> np.ndarray:
        """(3,) the lit lamp's position in the sample frame (mm) at the step."""

    def displaced_by_deg(self, config: RigConfig, actuators: Mapping[str, float]) -> float:
        """0 when the step's recorded view and light are its place in the sampling; else
        the most each lies from the pair the plan asked for, which the rig could not
        reach (deg)."""


_BY_KIND: dict[str, ModuleType] = {"wang": kinematics, "virtex": kinematics, "bonn": bonn}


def step_kinematics(config: RigConfig) -> StepKinematics:
    """The kinematics module of ``config``'s kind."""
    return cast(StepKinematics, _BY_KIND[config.kind])
