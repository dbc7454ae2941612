"""Each texel's capture moved to the slot's nominal directions by the fitted reflectance model.

A near lamp lights each texel from its own direction l_t (up to ±4.4° from the
slot's at 650 mm), and a perspective camera sees it along its own v_t (±3.6° at
800 mm). Resampling among the texel's own captures
(:mod:`processing.offline.texel_resample`) moves a sample onto the nominal
direction by blending neighbours that the plan placed 15–45° apart: exact for
a Lambertian texel, but a specular lobe 10° wide is not linear across such a
gap. This module instead asks the material's fitted glTF PBR model
(``rig process --stages pbr``, :mod:`processing.pbr`) how much the texel's
value changes between its own directions and the nominal ones, and scales the
capture by that ratio:

    value(l, v) = captured · M(l, v) / M(l_t, v_t) · cos θ_t / cos θ_c,

M the model's π f (n·l) of the texel; the last factor undoes the near-lamp
irradiance correction's reference-plane cosine where the light is moved
(:mod:`processing.offline.texel_light`: a capture holds f (n·l_t) cos θ_c / cos θ_t).
The model need only be right about the *change* over a few degrees, not about
the value: its error enters to first order in the turn. Where the model has
(almost) nothing to say — its value under :data:`MODEL_FLOOR` of the texel's
brightest, a light or view below the texel's horizon — or asks for more than a
factor :data:`MAX_RATIO`, the capture is kept as measured and counted.
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace

import numpy as np

from rig.geometry import direction_vector
from rig.material import PbrMaps, PbrParams, Radiometry, evaluate_pbr

__all__ = [
    "MAX_RATIO", "MODEL_FLOOR", "ModelMove", "model_params", "model_record", "moved_by_model",
]  # fmt: skip

#: A model value under this fraction of the texel's brightest (in the slot) says too
#: little: the capture is kept.
MODEL_FLOOR = 1e-3
#: A ratio beyond [1 / MAX_RATIO, MAX_RATIO] is the model's guess, not a small turn's
#: change: the capture is kept.
MAX_RATIO = 2.0

_PARAMS = tuple(f.name for f in fields(PbrParams))


@dataclass(frozen=True)
class ModelMove:
    """What :func:`moved_by_model` did to one view slot.

    kept : texel captures left as measured (the model too dark, or the ratio too large)
    captures : texel captures in all (lights × texels)
    largest : the largest factor applied (≥ 1: a ratio or its inverse)
    """

    kept: int = 0
    captures: int = 0
    largest: float = 1.0


def model_params(maps: PbrMaps) -> PbrParams:
    """The fitted maps as the model's parameters, one row per texel (row-major)."""
    count = maps.size * maps.size
    return PbrParams(**{
        name: np.asarray(getattr(maps, name)).reshape(count, *getattr(maps, name).shape[2:])
        for name in _PARAMS
    })  # fmt: skip


def moved_by_model(
    textures: np.ndarray,
    params: PbrParams,
    *,
    light_deg: np.ndarray,
    view_deg: tuple[float, float],
    own_lights: np.ndarray | None,
    centre_z: np.ndarray | None,
    own_view: np.ndarray | None,
) -> tuple[np.ndarray, ModelMove]:
    """One view slot's normtextures moved from each texel's own directions to the slot's.

    Parameters
    ----------
    textures : (L, n, n, C) float32, the slot's normtexture under each light
    params : the fitted model (:func:`model_params`), n² texels, C channels
    light_deg : (L, 2) the plan's (θ, φ) light directions, sample frame, degrees
    view_deg : the slot's (θ, φ) view direction
    own_lights : (L, n, n, 3) unit vectors to each capture's lamp from each texel
        (``texel_resample.texel_directions``), or None: the lights are not moved
    centre_z : (L,) the cosine of each lamp's direction at the sample's centre (the
        irradiance correction's reference), with ``own_lights``
    own_view : (n, n, 3) unit vectors to the camera from each texel, or None: the view is
        not moved

    Returns
    -------
    (L, n, n, C) float32 at the nominal directions, as measured where kept; ModelMove
    """
    lights, n = len(textures), textures.shape[1]
    nominal_light = direction_vector(light_deg[:, 0], light_deg[:, 1])  # (L, 3)
    nominal_view = np.broadcast_to(direction_vector(*view_deg), (lights, 3))
    texels = n * n
    shape = (texels, lights, 3)
    light_own = (np.broadcast_to(nominal_light, shape) if own_lights is None
                 else np.moveaxis(own_lights.reshape(lights, texels, 3), 0, 1))  # fmt: skip
    view_own = (np.broadcast_to(nominal_view, shape) if own_view is None
                else np.broadcast_to(own_view.reshape(texels, 1, 3), shape))  # fmt: skip
    target = evaluate_pbr(params, nominal_light, nominal_view)  # (T, L, C)
    own = evaluate_pbr(params, light_own, view_own)
    brightest = np.maximum(target.max(axis=1, keepdims=True), own.max(axis=1, keepdims=True))
    floor = MODEL_FLOOR * np.maximum(brightest, np.finfo(np.float64).tiny)
    usable = (own > floor) & (target > floor)
    ratio = np.where(usable, target / np.where(usable, own, 1.0), 1.0)
    if own_lights is not None:
        ratio = ratio * (light_own[..., 2] / centre_z[None, :])[..., None]
    wild = (ratio > MAX_RATIO) | (ratio < 1.0 / MAX_RATIO)
    kept = ~usable | wild
    ratio = np.where(kept, 1.0, ratio)
    # (T, L, C) → (L, n, n, C)
    factor = np.moveaxis(ratio, 1, 0).reshape(lights, n, n, -1).astype(np.float32)
    applied = ratio[~kept]
    largest = float(np.max(np.maximum(applied, 1.0 / applied))) if applied.size else 1.0
    kept_captures = int(np.moveaxis(kept.any(axis=-1), 1, 0).sum())
    return textures * factor, ModelMove(kept_captures, lights * texels, largest)


def model_record(
    radiometry: Radiometry, slots: list[ModelMove | str], *, lights: str, views: str
) -> Radiometry:
    """The material's record with what :func:`moved_by_model` did to each view slot with
    data (``slots``: its ModelMove, or why not): ``sources["model"]`` where any slot was
    moved; ``skipped["model"]``: the texel captures kept as measured, and the slots left
    as they were, with the reason."""
    moved = [r for r in slots if isinstance(r, ModelMove)]
    reasons = sorted({r for r in slots if isinstance(r, str)})
    said = []
    kept = sum(r.kept for r in moved)
    if kept:
        said.append(
            f"{kept} of {sum(r.captures for r in moved)} texel captures kept as measured (the "
            f"model under {MODEL_FLOOR:g} of the texel's brightest, or a factor beyond "
            f"{MAX_RATIO:g})"
        )
    if reasons:
        left = f"{len(slots) - len(moved)} of {len(slots)} view slots" if moved else "every slot"
        said.append(f"{'; '.join(reasons)}: {left} kept at the texels' own directions")
    skipped = radiometry.skipped | ({"model": "; ".join(said)} if said else {})
    sources = radiometry.sources
    if moved:
        what = " and ".join(
            name for name, option in (("lights", lights), ("views", views)) if option == "model"
        )
        largest = max(r.largest for r in moved)
        sources = sources | {"model": f"{what} moved by the fitted PBR model (factors up to "
                                      f"{largest:.3f})"}  # fmt: skip
    return replace(radiometry, sources=sources, skipped=skipped)
