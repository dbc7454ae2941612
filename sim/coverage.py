"""Which texels laser scans can reach: the reachable set of an MDF capture.

A texel of view v has an MDF value when the camera sees a surface point p
along its ray (seed ``001_…`` §3) *and* some laser sheet lights p in a way the
triangulation can use: the emitter sees p (nothing in between, p faces it),
the sheet through p lies within the unit's sweep, and it does not graze the
view ray (the error gain 1/|n·v| of ``processing.mdf``'s guard stays below
``max_error_gain``). Ray casting the scene mesh (trimesh, as the ground truth
does) gives that set per laser location, independent of any rendering;
:func:`choose_locations` then picks locations greedily until the union
covers a goal fraction of the visible texels.

A laser location is a direction (θ, φ) of the emitter in the sample frame,
θ from the zenith; θ must be one of the rig's mount angles
(``laser.mount_theta_deg``; a mount at −θ reaches the same directions with
the arc turned by 180°) and the kinematics (``rig.kinematics.inverse``) turn
it into arc and turntable angles. A steeper mount (smaller θ) sees down into
recesses that a 45° sheet never reaches; :func:`coverage_rows` sets coverage
against locations and mounts beside the capture time of the plan.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from pydantic import ValidationError

from rig.config import Laser, RigConfig
from rig.errors import ConfigError
from rig.geometry import direction_vector
from rig.plan import Plan
from rig.schedule import compile_plan
from sim.illumination import visible_from
from sim.model import SceneModel
from sim.truth import texel_hits

__all__ = [
    "LaserReach",
    "candidate_locations",
    "capture_s",
    "choose_locations",
    "coverage_rows",
    "laser_reach",
    "with_mounts",
]

_OFFSET_MM = 1e-3  # occlusion rays start this far off the surface


@dataclass(frozen=True)
class LaserReach:
    """The reachable set of one view.

    visible : (n, n) bool, the camera sees a surface along the texel's ray
    reached : (L, n, n) bool, location l's sheets reach the texel usably
    locations_deg : (L, 2) float64, (θ, φ) of each location, sample frame
    """

    visible: np.ndarray
    reached: np.ndarray
    locations_deg: np.ndarray

    def coverage(self, chosen=None) -> float:
        """Fraction of the visible texels that the ``chosen`` locations (indices;
        default all) reach between them."""
        picked = self.reached if chosen is None else self.reached[list(chosen)]
        union = np.any(picked, axis=0) & self.visible
        return float(union.sum() / max(int(self.visible.sum()), 1))


def candidate_locations(config: RigConfig, *, azimuths: int = 36) -> np.ndarray:
    """(L, 2) the laser locations the rig can produce: each mount's elevation
    (mounts at ±θ give the same) at ``azimuths`` evenly spaced azimuths."""
    if azimuths < 1:
        raise ValueError(f"azimuths={azimuths}: need ≥ 1")
    thetas = sorted({abs(float(t)) for t in config.laser.mount_theta_deg})
    phis = 360.0 * np.arange(azimuths) / azimuths
    return np.array([(theta, phi) for theta in thetas for phi in phis], dtype=np.float64)


def laser_reach(
    model: SceneModel,
    config: RigConfig,
    view_dir,
    locations_deg,
    n: int,
    *,
    max_error_gain: float = 10.0,
) -> LaserReach:
    """The texels of view ``view_dir`` (θ, φ) that each laser location reaches.

    Parameters
    ----------
    model : the scene's geometry (``Simulator.model``)
    config : the rig: the emitter's distance ``laser.radius_mm`` and the sweep
        ``laser.sweep_deg`` (the sheet through a point must lie within ± half
        of it of the sheet through the turntable centre)
    locations_deg : (L, 2) emitter directions (θ, φ), sample frame
    n : texels per side (the grid of ``rig.geometry.texel_centers_mm``)
    max_error_gain : sheets closer to the view ray than 1/|n·v| = this are
        useless to the triangulation (``MdfSettings.max_error_gain``)
    """
    locations = np.asarray(locations_deg, dtype=np.float64).reshape(-1, 2)
    if not np.all((locations[:, 0] > 0) & (locations[:, 0] < 90)):
        raise ValueError(
            f"locations_deg: θ must lie in (0°, 90°) (above the sample, not at the zenith "
            f"where the sheet is vertical), got {locations[:, 0].tolist()}"
        )
    hits, _ = texel_hits(model, view_dir, n)
    view = direction_vector(*view_dir)
    visible = np.zeros(n * n, dtype=bool)
    visible[hits.pixels] = True
    reached = np.zeros((len(locations), n * n), dtype=bool)
    half_sweep = np.deg2rad(config.laser.sweep_deg / 2)
    for i, (theta, phi) in enumerate(locations):
        source = config.laser.radius_mm * direction_vector(theta, phi)
        across = np.array([-np.sin(np.deg2rad(phi)), np.cos(np.deg2rad(phi)), 0.0])
        to_point = hits.points - source
        # The tilt that puts the sheet through p: the angle about `across`
        # between the ray to the turntable centre and the ray to p.
        along = np.cross(across, -source) / np.linalg.norm(source)
        tilt = np.arctan2(to_point @ along, to_point @ (-source / np.linalg.norm(source)))
        sheet_normal = np.cross(across, to_point)
        sheet_normal /= np.linalg.norm(sheet_normal, axis=1, keepdims=True)
        usable = (np.abs(tilt) <= half_sweep) & (
            np.abs(sheet_normal @ view) >= 1.0 / max_error_gain
        )
        facing = np.einsum("ij,ij->i", hits.normals, -to_point) > 0
        candidates = np.flatnonzero(usable & facing)
        lit = visible_from(model, _subset(hits, candidates), source, offset_mm=_OFFSET_MM)
        reached[i, hits.pixels[candidates[lit]]] = True
    return LaserReach(visible.reshape(n, n), reached.reshape(-1, n, n), locations)


def choose_locations(
    reach: LaserReach,
    *,
    goal: float = 0.99,
    start: Sequence[int] = (),
    max_locations: int | None = None,
) -> list[int]:
    """Indices of locations: ``start`` (e.g. the plan's own, for accuracy), then
    greedily the location that adds the most visible texels not yet reached,
    until ``goal`` of the visible texels are reached, no location adds any, or
    ``max_locations`` are chosen in all. The order is the order of choice."""
    if not 0 < goal <= 1:
        raise ValueError(f"goal={goal}: a fraction in (0, 1]")
    wanted = int(np.ceil(goal * reach.visible.sum()))
    remaining = reach.reached.reshape(len(reach.reached), -1) & reach.visible.reshape(1, -1)
    chosen = [int(i) for i in start]
    covered = np.any(remaining[chosen], axis=0)
    limit = len(remaining) if max_locations is None else max_locations
    while covered.sum() < wanted and len(chosen) < limit:
        gain = np.sum(remaining & ~covered, axis=1)
        best = int(np.argmax(gain))
        if gain[best] == 0:
            break
        chosen.append(best)
        covered |= remaining[best]
    return chosen


def capture_s(config: RigConfig, view_dir, locations_deg) -> float:
    """Estimated time (s) of an MDF capture of one view from ``locations_deg``
    on the rig ``config`` at the plan's default scan step (the schedule's
    estimate: moves, settling, sweeps)."""
    plan = Plan.model_validate({
        "sample": {"name": "coverage"},
        "captures": {"mdf": {
            "views": [list(view_dir)],
            "laser_locations": [[float(t), float(p)] for t, p in locations_deg],
        }},
    })  # fmt: skip
    return compile_plan(plan, config).estimate.total_s


def coverage_rows(
    model: SceneModel,
    config: RigConfig,
    view_dir,
    *,
    mounts: Sequence[Sequence[float]],
    even: Sequence[int] = (1, 5, 13, 26),
    start: int = 5,
    goal: float = 0.99,
    n: int = 128,
    azimuths: int = 36,
) -> list[dict]:
    """Coverage of view ``view_dir`` against laser locations and mounts, with
    the capture time: one row per mount set and way of choosing.

    A single mount: ``even`` locations evenly in azimuth (the seed's way).
    Several mounts (candidates: each at ``azimuths`` azimuths): the greedy
    choice to ``goal``, and the greedy completion of ``start`` even locations
    of the first mount (which keep its triangulation angle for most texels).
    Rows: ``mounts``, ``choice``, ``locations`` ((θ, φ) list), ``coverage``,
    ``capture_s`` (:func:`capture_s`).
    """
    rows = []
    for angles in mounts:
        rig = with_mounts(config, angles)
        choices = {}
        for k in even if len(angles) == 1 else ():
            locations = _even(abs(float(angles[0])), k)
            reach = laser_reach(model, rig, view_dir, locations, n)
            choices[f"{k} even at {abs(angles[0]):g}°"] = (locations, reach.coverage())
        if len(angles) > 1:
            begin = _even(abs(float(angles[0])), start)
            candidates = np.concatenate([begin, candidate_locations(rig, azimuths=azimuths)])
            reach = laser_reach(model, rig, view_dir, candidates, n)
            for choice, first in ((f"greedy to {goal:.0%}", ()),
                                  (f"{start} even + greedy", range(start))):  # fmt: skip
                picked = choose_locations(reach, goal=goal, start=first)
                choices[choice] = (candidates[picked], reach.coverage(picked))
        for choice, (locations, coverage) in choices.items():
            rows.append({
                "mounts": tuple(angles), "choice": choice, "locations": locations.tolist(),
                "coverage": coverage,
                "capture_s": capture_s(rig, view_dir, locations),
            })  # fmt: skip
    return rows


def with_mounts(config: RigConfig, angles: Sequence[float]) -> RigConfig:
    """``config`` with the laser mounts at ``angles`` (validated: ``ConfigError``
    naming ``laser.mount_theta_deg`` and what is valid)."""
    data = {**config.laser.model_dump(), "mount_theta_deg": [float(a) for a in angles]}
    try:
        laser = Laser.model_validate(data)
    except ValidationError as err:
        problems = "; ".join(
            ".".join(["laser", *map(str, e["loc"])]) + ": " + e["msg"].removeprefix("Value error, ")
            for e in err.errors()
        )
        raise ConfigError(problems) from None
    return config.model_copy(update={"laser": laser})


def _even(theta_deg: float, count: int) -> np.ndarray:
    """(count, 2) locations at ``theta_deg``, evenly in azimuth from 0°."""
    return np.column_stack([np.full(count, theta_deg), 360.0 * np.arange(count) / count])


def _subset(hits, rows: np.ndarray):
    """The hits at ``rows`` (points and normals are what ``visible_from`` reads)."""
    return type(hits)(
        hits.shape, hits.pixels[rows], hits.points[rows], hits.normals[rows], hits.faces[rows],
        hits.materials[rows], hits.parts[rows], hits.view_dirs[rows], hits.albedo[rows],
    )  # fmt: skip
