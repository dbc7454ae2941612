"""Compile a plan for the Bonn lab into ordered steps, and estimate the session.

Every wanted (view, light) pair is one step (one camera, one lamp): the arm
turns the plate and the rail moves the camera at once, the slower decides,
then the moved devices settle and the camera exposes. The lamp (an HMI bulb in
seed 000's lab) stays lit the whole session: it warms up once. Pairs the lab
cannot reach are refused before anything moves, each named.

Order: a nearest-neighbour tour from home over the modelled move time, or the
plan's own order where that is faster (a greedy tour can end in long jumps). The arm
moves its joints linearly (``movej``), which turns the plate along some path
between two orientations; a move whose path would tilt the plate past
``arm.max_tilt_deg`` on the way — turning the plate's back, and the arm
holding it, towards the rail — is made through the home orientation instead
(two moves, priced as such), so no move swings the arm into the camera's side.
"""

from __future__ import annotations

from collections import defaultdict
from typing import NamedTuple

import numpy as np

from rig.bonn import BonnPose, home_joints, home_rotation, inverse
from rig.config import RigConfig
from rig.errors import KinematicsError, PlanError
from rig.geometry import angular_distance_deg
from rig.parts import Axis
from rig.plan import Plan
from rig.steps import Estimate, Schedule, Shot, Step, frame_bytes, wanted_pairs
from rig.timing import shots_s
from rig.ur_kinematics import UR_MODELS
from rig.ur_kinematics import forward as arm_forward

__all__ = ["ArmRailPose", "compile_bonn", "motion_s"]

_PATH_SAMPLES = 8  # intermediate joint vectors checked along each arm move
_SHOWN = 5  # refused pairs named in full; the rest counted


class ArmRailPose(NamedTuple):
    """A Bonn step's pose: the rail position and the arm's joints (deg); ``via_home``: the
    arm goes through its home orientation first (its direct path would tilt the plate
    past ``arm.max_tilt_deg``)."""

    rail_deg: float
    joints_deg: tuple[float, ...]
    via_home: bool = False

    #: The read-backs a step's frames must still show after capture: the rail's (the arm
    #: reports its pose on arrival only).
    checked_axes = ("rail_deg",)

    def summary(self) -> str:
        """One line for a table of steps."""
        joints = ", ".join(f"{j:.1f}" for j in self.joints_deg)
        home = " via home" if self.via_home else ""
        return f"rail {self.rail_deg:.1f}°, joints ({joints})°{home}"


def compile_bonn(plan: Plan, config: RigConfig) -> Schedule:
    """Ordered steps for ``plan`` on the Bonn lab ``config``, with the estimate.

    Raises ``PlanError`` for captures the lab cannot do (``mdf``, ``fixed``)
    and for every (view, light) pair it cannot reach, named.
    """
    problems = [
        f"captures.{name}: the Bonn lab {why}; remove [captures.{name}]"
        for name, why in (("mdf", "has no laser unit"), ("fixed", "has no turntable or arc"))
        if getattr(plan.captures, name) is not None
    ]
    if problems:
        raise PlanError("plan vs rig config", problems)
    poses: list[tuple[str, tuple, tuple, BonnPose]] = []
    refused: dict[str, list[str]] = defaultdict(list)
    here = home_joints(config)
    for kind, view, light in wanted_pairs(plan):
        try:
            pose = inverse(config, view, light, current_rad=here)
        except KinematicsError as err:
            refused[kind].append(str(err))
            continue
        poses.append((kind, view, light, pose))
        here = pose.joints_rad
    if refused:
        lines = []
        for kind, errors in refused.items():
            lines += [f"captures.{kind}: {e}" for e in errors[:_SHOWN]]
            if len(errors) > _SHOWN:
                lines.append(f"captures.{kind}: and {len(errors) - _SHOWN} more pairs")
        raise PlanError("plan vs rig config", lines)
    exposures = tuple(plan.exposure.exposure_s * m for m in plan.exposure.hdr_brackets)
    naive = _steps(config, poses, range(len(poses)), exposures)
    tour = _steps(config, poses, _tour(config, [p[3] for p in poses]), exposures)
    naive_estimate, tour_estimate = _estimate(config, plan, naive), _estimate(config, plan, tour)
    # a greedy tour can end in long jumps: the plan's own order wins where it is faster
    steps, estimate = (
        (tour, tour_estimate)
        if tour_estimate.total_s <= naive_estimate.total_s
        else (naive, naive_estimate)
    )
    return Schedule(
        steps=steps,
        estimate=estimate,
        naive_estimate=naive_estimate,
        max_view_residual_deg=max((p[3].view_residual_deg for p in poses), default=0.0),
        max_light_residual_deg=max((p[3].light_residual_deg for p in poses), default=0.0),
        pairs=len(poses),
    )


def _joint_axis(config: RigConfig) -> Axis:
    device = config.bonn.arm.device
    return Axis(
        speed_deg_s=device.joint_speed_deg_s, accel_deg_s2=device.joint_accel_deg_s2,
        settle_s=device.settle_s, min_deg=-360.0, max_deg=360.0,
    )  # fmt: skip


def _move_s(config: RigConfig, q0, rail0, q1, rail1) -> tuple[np.ndarray, np.ndarray]:
    """Move and settle time (s) between arm joints (deg) and rail positions, broadcast."""
    joints, rail = _joint_axis(config), config.bonn.rail.axis
    d_arm = np.max(np.abs(np.asarray(q1) - q0), axis=-1)
    d_rail = np.abs(np.asarray(rail1) - rail0)
    move = np.maximum(joints.move_time_s(d_arm), rail.move_time_s(d_rail))
    settle = np.maximum(
        np.where(d_arm > 1e-9, joints.settle_s, 0.0), np.where(d_rail > 1e-9, rail.settle_s, 0.0)
    )
    return move, settle


def _tour(config: RigConfig, poses: list[BonnPose]) -> list[int]:
    """Indices of ``poses`` in nearest-neighbour order of move time from home."""
    if not poses:
        return []
    joints = np.degrees(np.array([p.joints_rad for p in poses]))
    rails = np.array([p.rail_deg for p in poses])
    q, rail = np.degrees(home_joints(config)), config.bonn.rail.axis.min_deg
    unvisited = np.ones(len(poses), dtype=bool)
    order = []
    for _ in range(len(poses)):
        idx = np.flatnonzero(unvisited)
        move, settle = _move_s(config, q, rail, joints[idx], rails[idx])
        nxt = int(idx[int(np.argmin(move + settle))])
        unvisited[nxt] = False
        order.append(nxt)
        q, rail = joints[nxt], rails[nxt]
    return order


def _path_tilts_deg(config: RigConfig, q0_deg, q1_deg) -> float:
    """Largest plate tilt from home (deg) along a linear joint move."""
    device = config.bonn.arm.device
    model = UR_MODELS[device.model]
    home_normal = home_rotation(config)[:, 2]
    worst = 0.0
    for s in np.linspace(0.0, 1.0, _PATH_SAMPLES + 2)[1:-1]:
        q = np.radians(np.asarray(q0_deg) + s * (np.asarray(q1_deg) - q0_deg))
        normal = arm_forward(q, model)[:3, 2]  # the tool z axis: the plate normal
        worst = max(worst, float(angular_distance_deg(normal, home_normal)))
    return worst


def _steps(config: RigConfig, poses, order, exposures) -> tuple[Step, ...]:
    camera = config.camera_arc.cameras[0].id
    lamp = config.bonn.lamp_id
    limit = config.bonn.arm.max_tilt_deg
    q = np.degrees(home_joints(config))
    steps = []
    for i, n in enumerate(order):
        kind, view, light, pose = poses[n]
        joints = np.degrees(pose.joints_rad)
        placed = ArmRailPose(
            pose.rail_deg, tuple(float(j) for j in joints),
            via_home=_path_tilts_deg(config, q, joints) > limit,
        )  # fmt: skip
        shot = Shot(camera, view, light, pose.view_residual_deg, pose.light_residual_deg)
        steps.append(Step(i, kind, placed, lamp, (shot,), exposures))
        q = joints
    return tuple(steps)


def motion_s(config: RigConfig, start: ArmRailPose, target: ArmRailPose):
    """Move and settle time (s) from one step's pose to the next's (through home where
    ``target.via_home``)."""
    q = np.array(start.joints_deg)
    if not target.via_home:
        return _move_s(config, q, start.rail_deg, np.array(target.joints_deg), target.rail_deg)
    home = np.degrees(home_joints(config))
    move0, settle0 = _move_s(config, q, start.rail_deg, home, start.rail_deg)
    move1, settle1 = _move_s(config, home, start.rail_deg, np.array(target.joints_deg),
                             target.rail_deg)  # fmt: skip
    return move0 + settle0 + move1, settle1


def _estimate(config: RigConfig, plan: Plan, steps: tuple[Step, ...]) -> Estimate:
    """Modelled duration and data size of ``steps`` in order (``rig.schedule.Estimate``)."""
    scale = plan.resolution.scale
    here = ArmRailPose(config.bonn.rail.axis.min_deg, tuple(np.degrees(home_joints(config))))
    motion = capture = 0.0
    by_kind: dict[str, float] = defaultdict(float)
    for step in steps:
        move, settle = motion_s(config, here, step.pose)
        moved = float(move + settle)
        shots = shots_s(config, step.cameras, step.exposures_s, scale=scale)
        motion += moved
        capture += shots
        by_kind[step.kind] += moved + shots
        here = step.pose
    lamp = 2 * config.lamp_bank.warmup_s if steps else 0.0  # on once, off once
    frames = sum(len(s.exposures_s) for s in steps)
    size = sum(len(s.exposures_s) * frame_bytes(config, s.cameras[0], scale) for s in steps)
    return Estimate(
        total_s=motion + lamp + capture, motion_s=motion, lamp_s=lamp, capture_s=capture,
        frames=frames, bytes=size, by_kind_s=dict(by_kind),
    )  # fmt: skip
