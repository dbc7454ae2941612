"""Direct illumination of surface hits: lamps, cast shadows, the laser sheet.

One function, :func:`direct_radiance`, used by both the rasterised frames and
the ray-cast truth; the effects it applies are passed in explicitly, and each
computation it makes is counted in ``counters`` (``stage.<name>``) so a test
can see that an unlisted effect costs nothing.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable

import numpy as np

from sim.model import SceneModel
from sim.scene import LaserParams
from sim.shading import LightSource, SurfaceHits, reflected_radiance, surface_radiance
from sim.world import WorldSnapshot

__all__ = ["direct_radiance", "laser_irradiance", "visible_from"]


def visible_from(
    model: SceneModel,
    hits: SurfaceHits,
    position: np.ndarray,
    *,
    offset_mm: float,
    where: np.ndarray | None = None,
) -> np.ndarray:
    """(n,) bool: the point ``position`` (sample frame, mm) sees each hit; with
    ``where`` (n,) bool, asked of those hits only (the others read False)."""
    origins = hits.reuse(("offset", offset_mm), lambda: hits.points + offset_mm * hits.normals)
    return model.caster.sees(origins, position, where)


def laser_irradiance(
    points: np.ndarray, source: np.ndarray, normal: np.ndarray, d: float, params: LaserParams
) -> tuple[np.ndarray, np.ndarray]:
    """Directions to the laser (n, 3) and its normal irradiance (n,), W/m².

    The sheet ``normal · x = d`` has a Gaussian cross-profile of σ =
    ``width_mm``; its power spreads over the fan's arc length at the distance
    r of the point: ``E = P / (√(2π) σ · r · fan) · exp(−δ² / 2σ²)`` with δ
    the distance of the point from the sheet (lengths in m).
    """
    to_src = source - points
    r = np.linalg.norm(to_src, axis=1)
    delta = points @ normal - d
    sigma = params.width_mm
    fan = np.deg2rad(params.fan_deg)
    peak = params.power_w / (np.sqrt(2 * np.pi) * (sigma / 1000) * (r / 1000) * fan)
    return to_src / r[:, None], peak * np.exp(-(delta**2) / (2 * sigma**2))


def direct_radiance(
    model: SceneModel,
    hits: SurfaceHits,
    snapshot: WorldSnapshot,
    *,
    counters: Counter,
    shadow_mask: Callable[[str, LightSource, np.ndarray], np.ndarray] | None,
    laser: LaserParams | None,
    specular: bool,
    offset_mm: float = 1e-3,
) -> np.ndarray:
    """Radiance (n, 3) W/(sr·m²) towards the camera from lamps and laser.

    ``shadow_mask(lamp_id, light, lit)`` returns the lamp's visibility of the hits
    (the ``shadows`` effect) where ``lit`` (n,) bool says the lamp's light falls (what
    it says elsewhere is multiplied by 0), or is None (no cast shadows). ``laser`` carries
    the sheet's parameters when the ``laser`` effect is listed; the laser is
    always occluded where its source cannot see the point.
    """
    lobes = model.specular if specular else None
    radiance = np.zeros((len(hits.points), 3))
    for lamp_id, light in model.lights(snapshot).items():
        counters["stage.lambert"] += 1
        dirs, e = light.surface_irradiance(hits.points, hits.normals)
        if shadow_mask is not None:
            counters["stage.shadows"] += 1
            e *= shadow_mask(lamp_id, light, e > 0)
        if lobes:
            counters["stage.specular"] += 1
        radiance += surface_radiance(hits, dirs, e, lobes)
    if laser is not None and snapshot.laser_on:
        counters["stage.laser"] += 1
        source, normal, d = model.laser_sheet(snapshot)
        dirs, e = laser_irradiance(hits.points, source, normal, d, laser)
        lit = e > 1e-9 * e.max(initial=0.0)
        if lit.any():
            sub = _subset(hits, lit)
            e[lit] *= visible_from(model, sub, source, offset_mm=offset_mm)
        e[~lit] = 0.0
        radiance += reflected_radiance(hits, dirs, e, lobes)
    return radiance


def _subset(hits: SurfaceHits, keep: np.ndarray) -> SurfaceHits:
    return SurfaceHits(
        shape=hits.shape,
        pixels=hits.pixels[keep],
        points=hits.points[keep],
        normals=hits.normals[keep],
        faces=hits.faces[keep],
        materials=hits.materials[keep],
        parts=hits.parts[keep],
        view_dirs=hits.view_dirs[keep],
        albedo=hits.albedo[keep],
    )
