"""Compile a plan for a rig of axes (a Wang rig, a VirTex stage) into ordered steps.

``compile_plan`` hands a plan to its rig kind's compiler (``rig.kinds``); the
Wang rig and the VirTex stage use :func:`compile_axes`. Each wanted (view,
light) pair goes through the kind's inverse kinematics to axis positions, a
camera and a lamp. Pairs that share turntable angle, arc angle and lamp become
one *step*: every camera that needs that lamp captures at once (the Wang rig's
cameras fire together). Steps at the same axis position run back to back;
positions are visited in a nearest-neighbour tour over the kind's modelled move
time, which the estimate compares with the plan's own order.
"""

from __future__ import annotations

import math
from collections import defaultdict
from collections.abc import Callable
from dataclasses import replace

import numpy as np

from rig.config import RigConfig
from rig.errors import ConfigError, PlanError
from rig.kinds import rig_kind
from rig.kinematics import forward
from rig.plan import Plan
from rig.steps import AxesPose, Estimate, Schedule, Shot, Step, frame_bytes, wanted_pairs
from rig.timing import motion_s, step_timing

__all__ = ["compile_axes", "compile_plan", "estimate"]

_KIND_ORDER = {"ps": 0, "btf": 1, "mdf": 2}

#: A kind's move and settle time (s) between two poses (``RigKind.motion_s``).
Motion = Callable[[RigConfig, AxesPose, AxesPose], tuple[np.ndarray, np.ndarray]]


def compile_plan(plan: Plan, config: RigConfig) -> Schedule:
    """Ordered steps for ``plan`` on the rig ``config``, with the estimate (by its kind)."""
    return rig_kind(config).compile(plan, config)


def _check_plan_fits_rig(plan: Plan, config: RigConfig) -> None:
    problems = []
    if plan.captures.mdf is not None:
        period = 1.0 / config.laser.frame_rate_hz
        if plan.exposure.laser_exposure_s > period:
            problems.append(
                f"exposure.laser_exposure_s: {plan.exposure.laser_exposure_s} s is longer "
                f"than the scan frame period {period:.4f} s "
                f"(laser.frame_rate_hz = {config.laser.frame_rate_hz}); use ≤ {period:.4f}"
            )
    for i, shot in enumerate(plan.captures.fixed or ()):
        for name, check, ids in (("lamp", config.lamp, (shot.lamp,)),
                                 ("cameras", config.camera, shot.cameras or ())):  # fmt: skip
            for item in ids:
                try:
                    check(item)
                except ConfigError as err:
                    problems.append(f"captures.fixed[{i}].{name}: {err}")
    if problems:
        raise PlanError("plan vs rig config", problems)


def _fixed_groups(plan: Plan, config: RigConfig, groups: dict) -> int:
    """Add the plan's fixed shots to ``groups`` (as BTF steps); their count."""
    everyone = tuple(c.id for c in config.camera_arc.cameras)
    n = 0
    for shot in plan.captures.fixed or ():
        gkey = ("btf", round(shot.turntable_deg, 6), round(shot.arc_deg, 6), shot.lamp)
        for camera in shot.cameras or everyone:
            view, light = forward(config, turntable_deg=shot.turntable_deg,
                                  arc_deg=shot.arc_deg, camera=camera, lamp=shot.lamp)  # fmt: skip
            pair = (tuple(float(a) for a in view), tuple(float(a) for a in light))
            groups[gkey].setdefault(camera, Shot(camera, *pair, 0.0, 0.0))
            n += 1
    return n


def compile_axes(
    plan: Plan,
    config: RigConfig,
    *,
    inverse: Callable,
    motion: Motion = motion_s,
    check_pair: Callable | None = None,
) -> Schedule:
    """Ordered steps for ``plan`` on a rig of axes, with the estimate.

    ``inverse(config, view, light, sources=…)`` is the kind's inverse kinematics (a
    ``rig.kinematics.RigPose``), ``motion`` its move-time model and
    ``check_pair(kind, view, light, pose)`` refuses a pair the kind would only
    approximate (``PlanError``).
    """
    _check_plan_fits_rig(plan, config)
    groups: dict[tuple, dict[str, Shot]] = defaultdict(dict)
    poses_cache: dict[tuple, object] = {}
    max_v = max_l = 0.0
    n_pairs = 0
    for kind, view, light in wanted_pairs(plan):
        n_pairs += 1
        key = (view, light, kind == "mdf")
        pose = poses_cache.get(key)
        if pose is None:
            sources = "laser" if kind == "mdf" else "lamps"
            pose = poses_cache[key] = inverse(config, view, light, sources=sources)
        if check_pair is not None:
            check_pair(kind, view, light, pose)
        max_v = max(max_v, pose.view_residual_deg)
        max_l = max(max_l, pose.light_residual_deg)
        gkey = (kind, round(pose.turntable_deg, 6), round(pose.arc_deg, 6), pose.lamp)
        groups[gkey].setdefault(
            pose.camera,
            Shot(pose.camera, view, light, pose.view_residual_deg, pose.light_residual_deg),
        )
    n_pairs += _fixed_groups(plan, config, groups)
    naive_keys = list(groups)  # insertion order = the plan's order
    tour = _nearest_neighbour_tour(naive_keys, config, motion)
    steps = _make_steps(tour, groups, plan, config)
    naive_steps = _make_steps(naive_keys, groups, plan, config)
    return Schedule(
        steps=steps,
        estimate=estimate(steps, plan, config, motion),
        naive_estimate=estimate(naive_steps, plan, config, motion),
        max_view_residual_deg=max_v,
        max_light_residual_deg=max_l,
        pairs=n_pairs,
    )


def _make_steps(keys, groups, plan: Plan, config: RigConfig) -> tuple[Step, ...]:
    exp = plan.exposure
    lamp_exposures = tuple(exp.exposure_s * m for m in exp.hdr_brackets)
    steps = []
    for i, key in enumerate(keys):
        kind, tt, arc, source = key
        pose = AxesPose(tt, arc)
        shots = tuple(sorted(groups[key].values(), key=lambda s: s.camera))
        if kind == "mdf":
            sweep = config.laser.sweep_deg
            frames = math.ceil(sweep / plan.captures.mdf.scan_step_deg) + 1
            steps.append(
                Step(
                    i,
                    kind,
                    pose,
                    source,
                    shots,
                    (exp.laser_exposure_s,),
                    frames,
                    (-sweep / 2, sweep / 2),
                )
            )
        else:
            steps.append(Step(i, kind, pose, source, shots, lamp_exposures))
    return tuple(steps)


def _nearest_neighbour_tour(keys: list[tuple], config: RigConfig, motion: Motion) -> list[tuple]:
    """Visit actuator positions greedily by modelled move time from home (0, 0).

    All steps at one position stay together (lamps, then laser scans).
    """
    by_pos: dict[tuple[float, float], list[tuple]] = defaultdict(list)
    for key in keys:
        by_pos[(key[1], key[2])].append(key)
    positions = np.array(list(by_pos), dtype=np.float64).reshape(-1, 2)
    order = []
    unvisited = np.ones(len(positions), dtype=bool)
    here = _home(config)
    for _ in range(len(positions)):
        idx = np.flatnonzero(unvisited)
        move, settle = motion(config, here, AxesPose(positions[idx, 0], positions[idx, 1]))
        cost = move + settle
        nxt = idx[int(np.argmin(cost))]
        unvisited[nxt] = False
        order.append(nxt)
        here = tuple(positions[nxt])
    tour = []
    pos_keys = list(by_pos)
    for p in order:
        tour.extend(sorted(by_pos[pos_keys[p]], key=lambda k: (_KIND_ORDER[k[0]], k[3])))
    return tour


def _home(config: RigConfig) -> AxesPose:
    return AxesPose(config.turntable.axis.min_deg, config.light_arc.axis.min_deg)


def estimate(steps, plan: Plan, config: RigConfig, move_model: Motion = motion_s) -> Estimate:
    """Modelled duration (:mod:`rig.timing`, moves by ``move_model``) and data size of
    ``steps`` executed in order."""
    scale = plan.resolution.scale
    here = _home(config)
    motion = lamp = capture = 0.0
    frames = size = 0
    by_kind: dict[str, float] = defaultdict(float)
    steps = list(steps)
    for step, before, after in zip(steps, [None, *steps[:-1]], [*steps[1:], None], strict=True):
        timing = step_timing(config, step, here, scale=scale, motion=move_model)
        if step.kind != "mdf":  # a lamp the neighbouring step uses too stays lit (the session)
            switches = (before is None or before.source != step.source) + (
                after is None or after.source != step.source
            )
            timing = replace(timing, lamp_s=switches * config.lamp_bank.warmup_s)
        here = step.pose
        motion += timing.move_s + timing.settle_s
        lamp += timing.lamp_s
        capture += timing.capture_s
        by_kind[step.kind] += timing.total_s
        n = step.frames_per_camera
        frames += n * len(step.cameras)
        size += sum(n * frame_bytes(config, c, scale) for c in step.cameras)
    return Estimate(
        total_s=motion + lamp + capture,
        motion_s=motion,
        lamp_s=lamp,
        capture_s=capture,
        frames=frames,
        bytes=size,
        by_kind_s=dict(by_kind),
    )
