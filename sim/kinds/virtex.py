"""The simulated VirTex stage: the camera above the sample, the lamps fixed on their ring."""

from __future__ import annotations

import numpy as np

from rig.config import RigConfig
from rig.kinds import rig_kind
from sim.kinds import SIM_KINDS
from sim.world import WorldSnapshot

__all__ = ["VirtexWorld"]


class VirtexWorld:
    """The stage's camera and lamps stand still."""

    def camera(self, config: RigConfig, camera_id: str, snapshot: WorldSnapshot | None):
        return config.camera_model(camera_id)

    def lamp_mm(self, config: RigConfig, lamp_id: str, snapshot: WorldSnapshot) -> np.ndarray:
        return rig_kind(config).recorded_lamp_mm(config, lamp_id, {})  # nothing moves

    def mount_offset_mm(self, config: RigConfig, offset_mm, snapshot: WorldSnapshot) -> np.ndarray:
        """The ring stands still: an offset in the stage's frame is one in the sample's."""
        return np.asarray(offset_mm, dtype=np.float64)


SIM_KINDS.register("sim", "virtex")(VirtexWorld())
