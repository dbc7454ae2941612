"""What a Bonn step records of the arm and the rail, for tests that build step records."""

from __future__ import annotations

import numpy as np

from rig.ur_kinematics import Pose


def recorded_actuators(rotation: np.ndarray, rail_deg: float) -> dict[str, float]:
    """The ``rail_deg`` and ``tool_r{x,y,z}_deg`` (rotation vector) a step records of a plate
    held at ``rotation`` (3, 3) with the camera at ``rail_deg``."""
    transform = np.eye(4)
    transform[:3, :3] = rotation
    rotvec = np.degrees(Pose.from_matrix(transform).rotvec)
    tool = {f"tool_r{c}_deg": float(r) for c, r in zip("xyz", rotvec, strict=True)}
    return {"rail_deg": float(rail_deg), **tool}
