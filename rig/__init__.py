"""btfrig's bottom layer: the rig's model, what a rig is and what it records.

Config, geometry, kinematics, plans, schedule and timing, the session archive,
the calibration file, the camera model, the clock and the errors. It imports
nothing of btfrig's; every other package may use it.
"""

from rig.camera import OrthographicCamera, PinholeCamera, look_at
from rig.clock import Clock, RealClock, VirtualClock
from rig.config import RigConfig, default_rig_config, load_rig_config
from rig.errors import ConfigError, KinematicsError, PlanError, RigError
from rig.geometry import (
    Interpolation,
    Sampling,
    angular_distance_deg,
    barycentric_weights,
    direction_angles,
    direction_vector,
    nearest_directions,
    texel_centers_mm,
)
from rig.kinematics import RigPose, forward, inverse, laser_plane, sampling_residuals
from rig.plan import Plan, load_plan, parse_plan
from rig.schedule import compile_plan
from rig.steps import Estimate, Schedule, Step

__all__ = [
    "Clock",
    "ConfigError",
    "Estimate",
    "Interpolation",
    "KinematicsError",
    "OrthographicCamera",
    "PinholeCamera",
    "Plan",
    "PlanError",
    "RealClock",
    "RigConfig",
    "RigError",
    "RigPose",
    "Sampling",
    "Schedule",
    "Step",
    "VirtualClock",
    "angular_distance_deg",
    "barycentric_weights",
    "compile_plan",
    "default_rig_config",
    "direction_angles",
    "direction_vector",
    "forward",
    "inverse",
    "laser_plane",
    "load_plan",
    "load_rig_config",
    "look_at",
    "nearest_directions",
    "parse_plan",
    "sampling_residuals",
    "texel_centers_mm",
]
