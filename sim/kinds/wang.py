"""The simulated Wang rig: cameras on the fixed arc, lamps on the light arc."""

from __future__ import annotations

import numpy as np

from rig.config import RigConfig
from rig.kinematics import lamp_position_mm
from sim.kinds import SIM_KINDS
from sim.world import WorldSnapshot

__all__ = ["WangWorld"]


class WangWorld:
    """Cameras fixed on their arc, lamps where the snapshot's arc and turntable put them."""

    def camera(self, config: RigConfig, camera_id: str, snapshot: WorldSnapshot | None):
        """The nominal camera, turntable at 0 (the renderer turns the rays by the snapshot's)."""
        return config.camera_model(camera_id)

    def lamp_mm(self, config: RigConfig, lamp_id: str, snapshot: WorldSnapshot) -> np.ndarray:
        return lamp_position_mm(
            config, lamp_id, arc_deg=snapshot.arc_deg, turntable_deg=snapshot.turntable_deg
        )


SIM_KINDS.register("sim", "wang")(WangWorld())
