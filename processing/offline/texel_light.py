"""Per-texel irradiance of a near lamp, divided out of the ``btf`` stage's normtextures.

A BTF value is radiance per unit irradiance from a distant light in the slot's
light direction. The btf stage stores every texel of a light's frame in units
of the irradiance at the sample's centre (I / r², r the lamp's distance from
the turntable centre). A lamp at r = 650 mm from a 100 mm sample gives a texel
at distance r_t the irradiance I / r_t², from a direction turned by up to
±4.4°: on the reference plane, cos θ_t / r_t² against cos θ / r², −15…+17 %
across the sample at θ = 45°. This module divides that ratio (and a spot
lamp's cut-off) out of each texel, from where the lamps stood (the arc-0°
frame), turned to each step's recorded arc and turntable angles: exact for a
flat texel, first order for a tilted one (whose cos θ turns by a different
amount).

Where the lamps stood comes from the archive's calibration
(``rig calibrate lamps``: a near lamp's ``position_mm``) where it has one, else
from the rig config's lamp geometry (the nominal light arc); the material
records which. A calibrated lamp brighter or nearer than the config's gives the
sample's centre more irradiance: its calibrated k cos θ / r² over the config's
scales its texels too (the calibrated lamps' mean ratio set to 1: a white
target gives intensities relative to one another, not their absolute scale).
Directional lamps give every texel the same irradiance.

What the turn of the light's direction does to a tilted texel's shading (or to
a cast shadow) is left in the data unless the stage asks for per-texel light
directions (:func:`per_texel_lights`): then each texel's samples of a view
slot, lit from the texel's own directions to the placed lamps, are resampled
onto the plan's light directions (:mod:`processing.offline.texel_resample`),
exactly for a tilted Lambertian texel; a texel whose nominal direction lies
outside the hull of its own keeps its sample and is counted.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from processing.offline.texel_resample import blended, texel_directions, texel_resampling
from rig.calfile import CalibrationFile
from rig.config import RigConfig
from rig.geometry import texel_centers_mm
from rig.kinds import rig_kind
from rig.kinematics import rotate_z
from rig.material import Radiometry

__all__ = [
    "IRRADIANCE_FLOOR",
    "LampPositions",
    "LightResampling",
    "lamp_directions",
    "lamp_mm",
    "lamp_positions",
    "light_record",
    "per_texel_lights",
    "plane_irradiance",
    "texel_irradiance",
]

#: A texel the lamp lights with less than this fraction of the centre's
#: irradiance (outside a spot's cone, a lamp at the horizon) is divided by this
#: floor, not by ~0.
IRRADIANCE_FLOOR = 0.05


@dataclass(frozen=True)
class LampPositions:
    """Where the rig's near lamps stood with the arc at 0°, for per-texel irradiance.

    positions_mm : lamp id → (3,) float64 mm, arc-0° frame (point and spot lamps)
    source : where they come from (the calibration session, or the rig config)
    centre_gain : lamp id → the irradiance it gives the sample's centre over what the
        rig config's lamp gives there (calibrated lamps; 1 for the others)
    """

    positions_mm: dict[str, np.ndarray]
    source: str
    centre_gain: dict[str, float] = field(default_factory=dict)


def plane_irradiance(source: np.ndarray, points: np.ndarray) -> np.ndarray:
    """(…) cos θ / r² of a point lamp at ``source`` (3,) mm on the horizontal plane
    at ``points`` (…, 3) mm, in 1/mm² (negative where the lamp is below the plane)."""
    to_lamp = source - points
    r = np.linalg.norm(to_lamp, axis=-1)
    return to_lamp[..., 2] / r**3


def lamp_positions(config: RigConfig, calibration: CalibrationFile | None, source: str = ""):
    """The near lamps' arc-0° positions: calibrated where the calibration has a
    lamp's ``position_mm`` (``source``: that session), the rig config's nominal
    geometry for the rest; None
    when the rig has no near lamp on an arc (a Bonn lab's lamp moves with the
    plate: not modelled here)."""
    near = [lamp for lamp in config.lamps if lamp.kind != "directional"]
    kind = rig_kind(config)
    if not near or not kind.lamps_on_arc:
        return None
    calibrated = calibration.lamps if calibration is not None else {}
    positions, origins, gains = {}, set(), {}
    for lamp in near:
        result = calibrated.get(lamp.id)
        nominal = kind.recorded_lamp_mm(config, lamp.id, {})  # every axis at 0
        if result is not None and result.position_mm is not None:
            positions[lamp.id] = np.asarray(result.position_mm, dtype=np.float64)
            origins.add(f"calibrated lamp positions, {source}")
            # the centre's irradiance k cos θ / r² as calibrated over the config's
            intensity = lamp.intensity if result.intensity is None else result.intensity
            gain = float(
                intensity
                * plane_irradiance(positions[lamp.id], np.zeros(3))
                / (lamp.intensity * plane_irradiance(nominal, np.zeros(3)))
            )
            if gain > 0:  # one at or below the plane lights nothing (texel_irradiance floors)
                gains[lamp.id] = gain
        else:
            positions[lamp.id] = nominal
            origins.add("the rig config's lamp geometry (nominal)")
    if gains:  # relative intensities carry no absolute scale: their mean keeps the config's
        mean = float(np.mean(list(gains.values())))
        gains = {k: g / mean for k, g in gains.items()}
    return LampPositions(positions, "; ".join(sorted(origins)), gains)


def texel_irradiance(
    positions: LampPositions,
    config: RigConfig,
    lamp: str,
    *,
    sample_mm: float,
    size: int,
    arc_deg: float,
    turntable_deg: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Irradiance on the texel grid over the sample centre's, for one step's lamp:
    cos θ / r² on the reference plane z = 0 (:func:`plane_irradiance`), the lamp at
    its arc-0° position turned by ``arc_deg − turntable_deg`` about the vertical axis;
    times the lamp's ``centre_gain`` (a calibrated lamp brighter at the centre than
    the config's).

    Returns
    -------
    ratio : (size, size) float64, ≥ ``IRRADIANCE_FLOOR`` (1 for a directional lamp)
    floored : (size, size) bool, texels the lamp barely lights (ratio floored)
    """
    source = lamp_mm(positions, lamp, arc_deg=arc_deg, turntable_deg=turntable_deg)
    if source is None:
        return np.ones((size, size)), np.zeros((size, size), bool)
    points = np.concatenate([texel_centers_mm(sample_mm, size), np.zeros((size, size, 1))], -1)
    centre = plane_irradiance(source, np.zeros(3))
    if not centre > 0:  # the lamp at or below the horizon: it lights nothing
        return np.full((size, size), IRRADIANCE_FLOOR), np.ones((size, size), bool)
    ratio = plane_irradiance(source, points) / centre * positions.centre_gain.get(lamp, 1.0)
    spec = config.lamp(lamp)
    if spec.kind == "spot":
        to_lamp = source - points
        axis = -source / np.linalg.norm(source)
        cos_off = np.einsum("...j,j->...", -to_lamp, axis) / np.linalg.norm(to_lamp, axis=-1)
        ratio = np.where(cos_off >= np.cos(np.deg2rad(spec.spot_cutoff_deg)), ratio, 0.0)
    floored = ratio < IRRADIANCE_FLOOR
    return np.maximum(ratio, IRRADIANCE_FLOOR), floored


def lamp_mm(
    positions: LampPositions, lamp: str, *, arc_deg: float, turntable_deg: float
) -> np.ndarray | None:
    """(3,) mm, sample frame: a step's lamp, its arc-0° position turned by
    ``arc_deg − turntable_deg`` about the vertical axis; None for a lamp not placed
    (a directional one)."""
    if lamp not in positions.positions_mm:
        return None
    return rotate_z(positions.positions_mm[lamp], arc_deg - turntable_deg)


@dataclass(frozen=True)
class LightResampling:
    """What :func:`per_texel_lights` did to one view slot's texel captures.

    outside : texel captures whose nominal light direction lies outside the hull of the
        texel's own: kept as measured
    captures : texel captures in all (lights × texels)
    worst_deg : the largest turn between own and nominal direction among those kept (°)
    skipped : why nothing was resampled (every texel keeps its own light), or None
    """

    outside: int = 0
    captures: int = 0
    worst_deg: float = 0.0
    skipped: str | None = None


def lamp_directions(
    lamps_mm: list[np.ndarray | None], *, sample_mm: float, size: int
) -> tuple[np.ndarray, np.ndarray] | str:
    """Each texel's own light: (L, size, size, 3) unit vectors from each texel to each
    capture's lamp (:func:`lamp_mm`), and (L,) the cosine of each lamp's direction at the
    sample's centre (the irradiance correction's reference); or why there are none."""
    if any(source is None for source in lamps_mm):
        return "directional lamps: every texel is lit from the slot's light direction"
    own = np.stack([texel_directions(source, sample_mm, size) for source in lamps_mm])
    if not own[..., 2].min() > 0.0:
        return "a lamp at or below some texel's horizon"
    return own, np.array([source[2] / np.linalg.norm(source) for source in lamps_mm])


def per_texel_lights(
    textures: np.ndarray, lamps_mm: list[np.ndarray | None], nominal_deg: np.ndarray, *,
    sample_mm: float,
) -> tuple[np.ndarray, LightResampling]:  # fmt: skip
    """One view slot's normtextures moved from each texel's own light directions onto
    the plan's.

    A normtexture holds, at texel t under lamp k, ρ/π n·l_t · cos θ_c / cos θ_t for a
    Lambertian texel (its irradiance divided out on the reference plane,
    :func:`texel_irradiance`: exact for a flat texel). Times cos θ_t / cos θ_c it is
    ρ/π n·l_t, linear in t's own direction l_t to the lamp, and blended with weights
    that reproduce the nominal direction from the texel's own
    (``texel_resampling(exact_for="linear")``) it is the value at the nominal light:
    exact for a tilted Lambertian texel, whatever its tilt. Cast shadows and specular
    lobes are interpolated as they fall.

    Parameters
    ----------
    textures : (L, n, n, C) float32, the slot's normtexture under each light
    lamps_mm : L × (3,) mm, sample frame, each capture's lamp (:func:`lamp_mm`), or None
        where the lamp is not placed
    nominal_deg : (L, 2) the plan's (θ, φ) light directions, sample frame, degrees
    sample_mm : the sample's side, mm

    Returns
    -------
    textures : (L, n, n, C) float32, at the nominal light directions where each texel's
        own surround them, as measured elsewhere (``textures`` itself when skipped)
    record : LightResampling
    """
    found = lamp_directions(lamps_mm, sample_mm=sample_mm, size=textures.shape[1])
    why = found if isinstance(found, str) else None
    if why is None and len(lamps_mm) < 3:
        why = f"{len(lamps_mm)} light(s) per view: no hull of light directions to resample in"
    if why is None:
        own, centre_z = found
        try:
            plan = texel_resampling(np.asarray(nominal_deg, np.float64), own, exact_for="linear")
        except ValueError as err:  # the lights on one great circle
            why = f"the light directions span no hull ({err})"
    if why is not None:
        return textures, LightResampling(skipped=why)
    linear = textures * (own[..., 2] / centre_z[:, None, None])[..., None].astype(np.float32)
    moved = np.stack([
        blended(plan, i, {int(k): linear[k] for k in np.unique(plan.indices[i])})
        for i in range(len(textures))
    ])  # fmt: skip
    moved = np.where(plan.outside[..., None], textures, moved)  # kept as measured
    kept = plan.turn_deg[plan.outside]
    worst = float(kept.max()) if kept.size else 0.0
    return moved, LightResampling(int(plan.outside.sum()), plan.outside.size, worst)


def light_record(radiometry: Radiometry, slots: list[LightResampling]) -> Radiometry:
    """The material's record with what :func:`per_texel_lights` did to each view slot
    with data: ``sources["light"]`` (the lamps' source, as the irradiance's) where any
    slot was resampled; ``skipped["light"]``: the texel captures kept as measured, and
    the slots left as they were, with the reason."""
    moved = [r for r in slots if r.skipped is None]
    reasons = sorted({r.skipped for r in slots if r.skipped is not None})
    said = []
    outside = sum(r.outside for r in moved)
    if outside:
        said.append(
            f"{outside} of {sum(r.captures for r in moved)} texel captures outside the hull "
            f"of the light directions that texel was lit from: kept as measured (up to "
            f"{max(r.worst_deg for r in moved):.1f}° off)"
        )
    if reasons:
        left = f"{len(slots) - len(moved)} of {len(slots)} view slots" if moved else "every slot"
        said.append(f"{'; '.join(reasons)}: {left} keeps each capture at the slot's nominal "
                    "light direction")  # fmt: skip
    skipped = radiometry.skipped | ({"light": "; ".join(said)} if said else {})
    sources = radiometry.sources
    if moved:
        sources = sources | {"light": sources["irradiance"]}
    return replace(radiometry, sources=sources, skipped=skipped)
