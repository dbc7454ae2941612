"""Kinematics of the Bonn lab (seed 000 §3.1): plate orientation + rail position ↔ directions.

In the lab frame (``rig.kind_sections``) the lamp lies along +x and rail position γ puts
the camera at azimuth γ in the horizontal plane; both are seen from the plate
centre, where the arm holds the sample. The arm's orientation of the plate is
the rotation ``R`` taking sample-frame vectors to lab vectors, so the view and
light directions in the sample frame are ``Rᵀ·c(γ)`` and ``Rᵀ·x``.

Inverse: the angle between the wanted view and light is the angle between the
camera and the lamp seen from the plate, so it fixes γ; the orientation is then
the rotation taking the pair onto (camera, lamp). Where γ falls outside the rail
(a view next to the light: the camera would stand in the lamp's beam) the rail
stops at its end and the orientation that best fits both directions (Wahba's
problem for two equally weighted vectors: bisectors onto each other) splits the
error evenly between them; the angular residuals say by how much. The
orientation must be within ``arm.max_tilt_deg`` of the arm's home and one the
UR arm reaches within its joint limits (``rig.ur_kinematics``); a pair that
needs any other is refused naming it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rig.camera import PinholeCamera, look_at
from rig.config import RigConfig
from rig.errors import KinematicsError
from rig.geometry import angular_distance_deg, direction_angles, direction_vector
from rig.ur_kinematics import UR_MODELS, Pose, nearest_joints
from rig.ur_kinematics import forward as ur_forward

__all__ = [
    "BonnPose",
    "arm_joints",
    "camera_direction",
    "camera_model",
    "displaced_by_deg",
    "forward",
    "home_joints",
    "home_rotation",
    "inverse",
    "lamp_position_mm",
    "plate_rotation",
    "plate_tool_pose",
    "recorded_camera",
    "recorded_lamp_mm",
    "recorded_pose",
    "tilt_deg",
]

_LAMP = np.array([1.0, 0.0, 0.0])
# A recorded rail position this close to an axis end is at it (a servo's read-back
# is quantised to ~0.005° of rail at the default gear ratio).
_RAIL_END_DEG = 0.05


@dataclass(frozen=True)
class BonnPose:
    """A plate orientation and rail position, with the arm's joints that take it.

    ``rotation`` (3, 3) takes sample-frame vectors to the lab frame;
    ``joints_rad`` (6,) are the arm's joints; the residuals are the angles
    between the wanted and the achieved view and light directions.
    """

    rail_deg: float
    rotation: np.ndarray
    joints_rad: np.ndarray
    view_residual_deg: float = 0.0
    light_residual_deg: float = 0.0


def camera_model(config: RigConfig, camera_id: str, rotation: np.ndarray, rail_deg: float):
    """The rail camera's pinhole model in the sample frame of a plate held at ``rotation``.

    The camera sits ``rail.radius_mm`` out at azimuth ``rail_deg``, looking at the
    plate centre, image up along the lab's z.
    """
    lab = _bonn(config)
    nominal = config.camera_model(camera_id)  # intrinsics, distortion, size
    eye = lab.rail.radius_mm * camera_direction(rail_deg)
    r_cam, t = look_at(eye, np.zeros(3), up=np.array([0.0, 0.0, 1.0]))
    return PinholeCamera(nominal.K, nominal.dist, r_cam @ rotation, t, nominal.width,
                         nominal.height)  # fmt: skip


def recorded_camera(config: RigConfig, camera_id: str, actuators: dict) -> PinholeCamera:
    """The rail camera's model in the sample frame at a step, from the arm's and the rail's
    recorded state (``StepRecord.actuators``: ``tool_rx_deg``, ``tool_ry_deg``,
    ``tool_rz_deg``, ``rail_deg``)."""
    rotation, rail_deg = recorded_pose(actuators)
    return camera_model(config, camera_id, rotation, rail_deg)


def recorded_pose(actuators: dict) -> tuple[np.ndarray, float]:
    """The plate's rotation (3, 3) and the rail position (°) a Bonn step recorded."""
    try:
        angles = [float(actuators[f"tool_r{c}_deg"]) for c in "xyz"]
        rail_deg = float(actuators["rail_deg"])
    except KeyError as err:
        raise KinematicsError(
            f"the step's recorded actuators lack {err.args[0]!r}; a Bonn step records "
            "tool_rx_deg, tool_ry_deg, tool_rz_deg and rail_deg"
        ) from err
    return Pose((0.0, 0.0, 0.0), tuple(np.radians(angles))).matrix()[:3, :3], rail_deg


def lamp_position_mm(config: RigConfig, rotation: np.ndarray) -> np.ndarray:
    """(3,) the lamp's position (mm) in the sample frame of a plate held at ``rotation``."""
    return rotation.T @ (_bonn(config).lamp_distance_mm * _LAMP)


def recorded_lamp_mm(config: RigConfig, lamp_id: str, actuators) -> np.ndarray:
    """(3,) the lab's lamp (``lamp_id``, its one) in the sample frame (mm) at a step, from
    the plate rotation the step recorded (:func:`recorded_pose`)."""
    if lamp_id != _bonn(config).lamp_id:
        raise KinematicsError(
            f"lamp {lamp_id!r}: the Bonn lab has one lamp, {config.bonn.lamp_id!r}"
        )
    return lamp_position_mm(config, recorded_pose(actuators)[0])


def displaced_by_deg(config: RigConfig, actuators) -> float:
    """The most (deg) each of a step's recorded view and light lies from the pair it was
    asked for: 0 unless the rail stood at an end (:func:`inverse`).

    A pair whose view and light are closer than ``rail.axis.min_deg`` (a retro-reflection
    pair: view = light) or further apart than ``max_deg`` leaves the rail at that end;
    both directions then turn by half the shortfall about their shared bisector, so each
    lies at most ``min_deg / 2`` (``(180 − max_deg) / 2``) from the one asked for.
    """
    axis = _bonn(config).rail.axis
    _, rail_deg = recorded_pose(actuators)
    if rail_deg <= axis.min_deg + _RAIL_END_DEG:
        return axis.min_deg / 2
    if rail_deg >= axis.max_deg - _RAIL_END_DEG:
        return (180.0 - axis.max_deg) / 2
    return 0.0


def _bonn(config: RigConfig):
    if config.bonn is None:
        raise KinematicsError(
            f"rig.bonn needs a rig config with a [bonn] section; this one is a {config.kind!r} rig"
        )
    return config.bonn


def camera_direction(rail_deg: float) -> np.ndarray:
    """(3,) lab unit vector from the plate centre to the camera at rail position ``rail_deg``."""
    g = np.deg2rad(rail_deg)
    return np.array([np.cos(g), np.sin(g), 0.0])


def home_rotation(config: RigConfig) -> np.ndarray:
    """(3, 3) the plate at home: normal horizontal at ``arm.home_azimuth_deg``, sample y up."""
    h = np.deg2rad(_bonn(config).arm.home_azimuth_deg)
    normal = np.array([np.cos(h), np.sin(h), 0.0])
    up = np.array([0.0, 0.0, 1.0])
    return np.column_stack([np.cross(up, normal), up, normal])


def tilt_deg(config: RigConfig, rotation: np.ndarray) -> float:
    """Angle (deg) between the plate normal of ``rotation`` and its normal at home."""
    return float(angular_distance_deg(rotation[:, 2], home_rotation(config)[:, 2]))


def forward(config: RigConfig, rotation: np.ndarray, rail_deg: float):
    """Sample-frame (θ, φ) in degrees of the view and the light: two (2,) arrays."""
    _bonn(config)
    view = rotation.T @ camera_direction(rail_deg)
    light = rotation.T @ _LAMP
    return np.array(direction_angles(view)), np.array(direction_angles(light))


def _pair_frame(first: np.ndarray, second: np.ndarray) -> np.ndarray:
    """(3, 3) orthonormal frame of a direction pair: bisector, half-difference, normal."""
    bisector = first + second
    if np.linalg.norm(bisector) < 1e-12:
        raise KinematicsError("opposite view and light directions have no orientation")
    bisector /= np.linalg.norm(bisector)
    across = first - second
    if np.linalg.norm(across) < 1e-12:  # view = light: any direction across the bisector
        helper = np.array([0.0, 0.0, 1.0]) if abs(bisector[2]) < 0.9 else np.array([1.0, 0, 0])
        across = np.cross(bisector, helper)
    across -= (across @ bisector) * bisector
    across /= np.linalg.norm(across)
    return np.column_stack([bisector, across, np.cross(bisector, across)])


def plate_tool_pose(config: RigConfig, rotation: np.ndarray) -> Pose:
    """The arm's tool pose (base frame) holding the plate centre at the lab origin.

    The tool frame is the sample frame: the flange holds the plate from behind,
    its z axis out through the plate's normal (the TCP is the plate centre).
    """
    arm = _bonn(config).arm
    t = np.eye(4)
    t[:3, :3] = rotation
    t[:3, 3] = -np.asarray(arm.base_mm, dtype=np.float64) / 1000.0
    return Pose.from_matrix(t)


def inverse(config: RigConfig, view_deg, light_deg, *, current_rad=None) -> BonnPose:
    """The plate orientation, rail position and arm joints that realise a (view, light) pair.

    Parameters
    ----------
    view_deg, light_deg : (θ, φ) in degrees, sample frame
    current_rad : (6,) the arm's joints now (default: home's); the joint
        solution nearest them is chosen

    Raises
    ------
    KinematicsError
        Naming the pair, when the orientation it needs tilts the plate past
        ``arm.max_tilt_deg`` or is one the arm cannot reach within its limits.
    """
    lab = _bonn(config)
    view = direction_vector(*view_deg)
    light = direction_vector(*light_deg)
    axis = lab.rail.axis
    rail = float(np.clip(angular_distance_deg(view, light), axis.min_deg, axis.max_deg))
    camera = camera_direction(rail)
    rotation = _pair_frame(camera, _LAMP) @ _pair_frame(view, light).T
    pair = "view ({:g}°, {:g}°), light ({:g}°, {:g}°)".format(*view_deg, *light_deg)
    tilt = tilt_deg(config, rotation)
    if tilt > lab.arm.max_tilt_deg:
        raise KinematicsError(
            f"{pair}: the plate would tilt {tilt:.1f}° from home, past the arm's "
            f"max_tilt_deg {lab.arm.max_tilt_deg:g}°"
        )
    joints = arm_joints(config, rotation, current_rad, pair=pair)
    got_view, got_light = rotation.T @ camera, rotation.T @ _LAMP
    return BonnPose(
        rail_deg=rail,
        rotation=rotation,
        joints_rad=joints,
        view_residual_deg=float(angular_distance_deg(got_view, view)),
        light_residual_deg=float(angular_distance_deg(got_light, light)),
    )


def plate_rotation(config: RigConfig, joints_rad) -> np.ndarray:
    """(3, 3) the plate's orientation (sample → lab) where the arm's joints hold it:
    its tool pose (the flange and the tool centre point) — :func:`plate_tool_pose` undone."""
    device = _bonn(config).arm.device
    flange = ur_forward(np.asarray(joints_rad, dtype=np.float64), UR_MODELS[device.model])
    return flange[:3, :3] @ Pose(device.tcp[:3], device.tcp[3:]).matrix()[:3, :3]


def arm_joints(config: RigConfig, rotation: np.ndarray, current_rad=None, *, pair: str = ""):
    """(6,) joints (rad) holding the plate at ``rotation``, nearest ``current_rad`` (home's).

    Raises ``KinematicsError`` naming ``pair`` when the arm cannot take it.
    """
    try:
        near = home_joints(config) if current_rad is None else current_rad
        return _joints(config, rotation, near)
    except KinematicsError as err:
        raise KinematicsError(f"{pair}: {err}" if pair else str(err)) from None


def home_joints(config: RigConfig) -> np.ndarray:
    """(6,) the arm's joints (rad) holding the plate at home."""
    return _joints(config, home_rotation(config), np.zeros(6))


def _joints(config: RigConfig, rotation: np.ndarray, near) -> np.ndarray:
    device = _bonn(config).arm.device
    limits = np.radians(np.column_stack([device.joint_min_deg, device.joint_max_deg]))
    tcp = Pose(device.tcp[:3], device.tcp[3:])
    return nearest_joints(
        plate_tool_pose(config, rotation), near, limits_rad=limits,
        model=UR_MODELS[device.model], tcp=tcp,
    )  # fmt: skip
