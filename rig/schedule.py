"""Compile a plan and a rig config into ordered steps, and estimate the session.

Each wanted (view, light) pair goes through the inverse kinematics to actuator
positions, a camera and a lamp. Pairs that share turntable angle, arc angle and
lamp become one *step*: every camera that needs that lamp captures at once (the
Wang rig's cameras fire together). Steps at the same actuator position run back
to back; positions are visited in a nearest-neighbour tour over the modelled
move time, which the estimate compares with the plan's own order.
"""

from __future__ import annotations

import math
from collections import defaultdict
from dataclasses import dataclass, field, replace

import numpy as np

from rig.config import RigConfig
from rig.errors import ConfigError, PlanError
from rig.kinematics import forward, inverse
from rig.plan import Plan
from rig.timing import motion_s, step_timing

__all__ = ["Estimate", "Schedule", "Shot", "Step", "compile_plan"]

_KIND_ORDER = {"ps": 0, "btf": 1, "mdf": 2}


@dataclass(frozen=True)
class Shot:
    """What one camera records in a step, in the sample frame (degrees)."""

    camera: str
    view_deg: tuple[float, float]
    light_deg: tuple[float, float]
    view_residual_deg: float
    light_residual_deg: float


@dataclass(frozen=True)
class Step:
    """One idempotent unit of work: move → settle → lamp/laser → capture → commit.

    ``exposures_s`` holds one exposure per frame for lamp steps (HDR brackets);
    a laser step records ``scan_frames`` frames per camera at the laser exposure
    while the sheet tilts from ``tilt_deg[0]`` to ``tilt_deg[1]``.
    """

    index: int
    kind: str
    turntable_deg: float
    arc_deg: float
    source: str
    shots: tuple[Shot, ...]
    exposures_s: tuple[float, ...]
    scan_frames: int = 0
    tilt_deg: tuple[float, float] | None = None

    @property
    def cameras(self) -> tuple[str, ...]:
        return tuple(s.camera for s in self.shots)

    @property
    def frames_per_camera(self) -> int:
        return self.scan_frames if self.kind == "mdf" else len(self.exposures_s)


@dataclass(frozen=True)
class Estimate:
    """Expected duration (s) and data size (bytes) of a schedule."""

    total_s: float
    motion_s: float
    lamp_s: float
    capture_s: float
    frames: int
    bytes: int
    by_kind_s: dict[str, float]


@dataclass(frozen=True)
class Schedule:
    steps: tuple[Step, ...]
    estimate: Estimate
    naive_estimate: Estimate
    max_view_residual_deg: float
    max_light_residual_deg: float
    pairs: int = field(default=0)


def _pairs(kind: str, views, lights):
    for v in views.resolve().directions:
        for light in lights.resolve().directions:
            yield kind, (float(v[0]), float(v[1])), (float(light[0]), float(light[1]))


def _wanted_pairs(plan: Plan):
    """(kind, view, light) in the plan's own order."""
    c = plan.captures
    if c.ps is not None:
        yield from _pairs("ps", c.ps.views, c.ps.lights)
    if c.btf is not None:
        yield from _pairs("btf", c.btf.views, c.btf.lights)
    if c.mdf is not None:
        yield from _pairs("mdf", c.mdf.views, c.mdf.laser_locations)


# What a VirTex stage cannot capture, and why (it has one zenith camera, fixed lamps).
_NOT_ON_VIRTEX = {
    "btf": "its one camera looks straight down, so it sees one view direction",
    "mdf": "it has no laser unit",
    "fixed": "it has no turntable or arc to position",
}
# A VirTex stage realises a wanted direction only as closely as this (deg).
_VIRTEX_TOLERANCE_DEG = 0.5


def _check_plan_fits_rig(plan: Plan, config: RigConfig) -> None:
    problems = []
    if config.kind == "virtex":
        for capture, why in _NOT_ON_VIRTEX.items():
            if getattr(plan.captures, capture) is not None:
                problems.append(
                    f"captures.{capture}: a VirTex stage captures photometric stereo only "
                    f"(captures.ps): {why}; remove [captures.{capture}] or use a rig config "
                    "of another kind"
                )
        if problems:
            raise PlanError("plan vs rig config", problems)
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


def _check_on_virtex(config: RigConfig, kind: str, view, light, pose) -> None:
    """Refuse a pair the stage would only approximate, naming it and what the stage has."""
    problems = []
    if pose.view_residual_deg > _VIRTEX_TOLERANCE_DEG:
        problems.append(
            f"captures.{kind}.views: view {view} is {pose.view_residual_deg:.1f}° from the "
            "stage camera's view (0, 0); a VirTex stage sees the sample from above only"
        )
    if pose.light_residual_deg > _VIRTEX_TOLERANCE_DEG:
        stage = config.virtex
        azimuths = ", ".join(f"{stage.azimuth_deg(i):g}" for i in range(stage.lamp_count))
        problems.append(
            f"captures.{kind}.lights: light {light} is {pose.light_residual_deg:.1f}° from the "
            f"nearest lamp ({pose.lamp}); the stage's lamps are at theta_deg "
            f"{stage.lamp_theta_deg:g}, phi_deg {azimuths}"
        )
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


def compile_plan(plan: Plan, config: RigConfig) -> Schedule:
    """Ordered steps for ``plan`` on the rig ``config``, with the estimate.

    A Bonn lab's plan compiles to ``rig.bonn_plan.BonnSchedule`` (one step per pair).
    """
    if config.kind == "bonn":
        from rig.bonn_plan import compile_bonn  # it builds on this module's estimate

        return compile_bonn(plan, config)
    _check_plan_fits_rig(plan, config)
    groups: dict[tuple, dict[str, Shot]] = defaultdict(dict)
    poses_cache: dict[tuple, object] = {}
    max_v = max_l = 0.0
    n_pairs = 0
    for kind, view, light in _wanted_pairs(plan):
        n_pairs += 1
        key = (view, light, kind == "mdf")
        pose = poses_cache.get(key)
        if pose is None:
            sources = "laser" if kind == "mdf" else "lamps"
            pose = poses_cache[key] = inverse(config, view, light, sources=sources)
        if config.kind == "virtex":
            _check_on_virtex(config, kind, view, light, pose)
        max_v = max(max_v, pose.view_residual_deg)
        max_l = max(max_l, pose.light_residual_deg)
        gkey = (kind, round(pose.turntable_deg, 6), round(pose.arc_deg, 6), pose.lamp)
        groups[gkey].setdefault(
            pose.camera,
            Shot(pose.camera, view, light, pose.view_residual_deg, pose.light_residual_deg),
        )
    n_pairs += _fixed_groups(plan, config, groups)
    naive_keys = list(groups)  # insertion order = the plan's order
    tour = _nearest_neighbour_tour(naive_keys, config)
    steps = _make_steps(tour, groups, plan, config)
    naive_steps = _make_steps(naive_keys, groups, plan, config)
    return Schedule(
        steps=steps,
        estimate=estimate(steps, plan, config),
        naive_estimate=estimate(naive_steps, plan, config),
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
        shots = tuple(sorted(groups[key].values(), key=lambda s: s.camera))
        if kind == "mdf":
            sweep = config.laser.sweep_deg
            frames = math.ceil(sweep / plan.captures.mdf.scan_step_deg) + 1
            steps.append(
                Step(
                    i,
                    kind,
                    tt,
                    arc,
                    source,
                    shots,
                    (exp.laser_exposure_s,),
                    frames,
                    (-sweep / 2, sweep / 2),
                )
            )
        else:
            steps.append(Step(i, kind, tt, arc, source, shots, lamp_exposures))
    return tuple(steps)


def _move_cost(config: RigConfig, tt0, arc0, tt1, arc1) -> np.ndarray:
    move, settle = motion_s(config, (tt0, arc0), (tt1, arc1))
    return move + settle


def _nearest_neighbour_tour(keys: list[tuple], config: RigConfig) -> list[tuple]:
    """Visit actuator positions greedily by modelled move time from home (0, 0).

    All steps at one position stay together (lamps, then laser scans).
    """
    by_pos: dict[tuple[float, float], list[tuple]] = defaultdict(list)
    for key in keys:
        by_pos[(key[1], key[2])].append(key)
    positions = np.array(list(by_pos), dtype=np.float64).reshape(-1, 2)
    order = []
    unvisited = np.ones(len(positions), dtype=bool)
    here = (config.turntable.axis.min_deg, config.light_arc.axis.min_deg)
    for _ in range(len(positions)):
        idx = np.flatnonzero(unvisited)
        cost = _move_cost(config, here[0], here[1], positions[idx, 0], positions[idx, 1])
        nxt = idx[int(np.argmin(cost))]
        unvisited[nxt] = False
        order.append(nxt)
        here = tuple(positions[nxt])
    tour = []
    pos_keys = list(by_pos)
    for p in order:
        tour.extend(sorted(by_pos[pos_keys[p]], key=lambda k: (_KIND_ORDER[k[0]], k[3])))
    return tour


def _frame_bytes(config: RigConfig, camera_id: str, scale: float) -> int:
    cam = config.camera(camera_id)
    w, h = max(1, round(cam.width * scale)), max(1, round(cam.height * scale))
    return w * h * cam.channels * (1 if cam.bit_depth == 8 else 2)


def estimate(steps, plan: Plan, config: RigConfig) -> Estimate:
    """Modelled duration (:mod:`rig.timing`) and data size of ``steps`` executed in order."""
    scale = plan.resolution.scale
    here = (config.turntable.axis.min_deg, config.light_arc.axis.min_deg)
    motion = lamp = capture = 0.0
    frames = size = 0
    by_kind: dict[str, float] = defaultdict(float)
    steps = list(steps)
    for step, before, after in zip(steps, [None, *steps[:-1]], [*steps[1:], None], strict=True):
        timing = step_timing(config, step, here, scale=scale)
        if step.kind != "mdf":  # a lamp the neighbouring step uses too stays lit (the session)
            switches = (before is None or before.source != step.source) + (
                after is None or after.source != step.source
            )
            timing = replace(timing, lamp_s=switches * config.lamp_bank.warmup_s)
        here = (step.turntable_deg, step.arc_deg)
        motion += timing.move_s + timing.settle_s
        lamp += timing.lamp_s
        capture += timing.capture_s
        by_kind[step.kind] += timing.total_s
        n = step.frames_per_camera
        frames += n * len(step.cameras)
        size += sum(n * _frame_bytes(config, c, scale) for c in step.cameras)
    return Estimate(
        total_s=motion + lamp + capture,
        motion_s=motion,
        lamp_s=lamp,
        capture_s=capture,
        frames=frames,
        bytes=size,
        by_kind_s=dict(by_kind),
    )
