"""The simulated Wang rig: cameras on the fixed arc, lamps on the light arc."""

from __future__ import annotations

import numpy as np

from rig.config import RigConfig
from rig.kinematics import lamp_position_mm, rotate_z
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

    def mount_offset_mm(self, config: RigConfig, offset_mm, snapshot: WorldSnapshot) -> np.ndarray:
        """An offset in the light arc's frame at arc 0°, turned with the arc and the turntable."""
        return rotate_z(offset_mm, snapshot.arc_deg - snapshot.turntable_deg)


SIM_KINDS.register("sim", "wang")(WangWorld())
