"""The simulated Bonn lab: the arm's joints turn the plate, the rail carries the camera."""

from __future__ import annotations

import numpy as np

from rig import bonn
from rig.config import RigConfig
from sim.kinds import SIM_KINDS
from sim.world import WorldSnapshot

__all__ = ["BonnWorld"]


class BonnWorld:
    """The plate turned by the arm, the camera on the rail, the lamp fixed in the lab."""

    def camera(self, config: RigConfig, camera_id: str, snapshot: WorldSnapshot | None):
        """Where the snapshot's plate rotation and rail put the camera (no snapshot: the
        nominal camera)."""
        if snapshot is None:
            return config.camera_model(camera_id)
        return bonn.camera_model(config, camera_id, snapshot.plate_rotation(), snapshot.rail_deg)

    def lamp_mm(self, config: RigConfig, lamp_id: str, snapshot: WorldSnapshot) -> np.ndarray:
        return bonn.lamp_position_mm(config, snapshot.plate_rotation())

    def mount_offset_mm(self, config: RigConfig, offset_mm, snapshot: WorldSnapshot) -> np.ndarray:
        """The lamp is fixed in the lab: an offset in the lab's frame, seen from the plate."""
        return snapshot.plate_rotation().T @ np.asarray(offset_mm, dtype=np.float64)


SIM_KINDS.register("sim", "bonn")(BonnWorld())
