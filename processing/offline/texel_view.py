"""Per-texel view directions of a perspective camera, and the BTF resampled onto the plan's views.

A camera 800 mm from a 100 mm sample sees each texel from its own direction:
the ray from the texel to the camera's centre turns by up to ±3.6° across the
sample. A view slot's normtexture therefore holds, at texel t, the BTF at t's
own view direction v_t, not at the slot's nominal one. This module places
every slot's camera (its calibrated centre in the sample frame, else the rig
config's nominal one), gives each texel its own direction per slot, and
resamples each texel onto the plan's grid
(:mod:`processing.offline.texel_resample`: the barycentric blend of the texel's
own measured views around each nominal one; outside the texel's own hull it
keeps its measurement and is counted as flagged).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from processing.btf import CompressedBTF, compress_view
from processing.offline.radiometry import calibration_source
from processing.offline.runner import archive_calibration, frame_camera
from processing.offline.texel_resample import (
    TexelResampling,
    blended,
    texel_directions,
    texel_resampling,
)
from rig.archive import Archive
from rig.config import RigConfig
from rig.interchange import imported_normtextures
from rig.kinds import rig_kind
from rig.material import Radiometry

__all__ = ["SlotCamera", "per_texel_views", "slot_camera"]


@dataclass(frozen=True)
class SlotCamera:
    """Where a view slot's camera stood, for its texels' own view directions.

    centre_mm : (3,) float64 mm, sample frame; None where it cannot be placed
    source : the calibration session or the rig config it comes from; or why not placed
    """

    centre_mm: np.ndarray | None
    source: str


def slot_camera(archive: Archive, config: RigConfig, slot) -> SlotCamera:
    """The camera of a view slot (``processing.offline.btf.BtfSlot``) at its first
    capture's turntable angle: calibrated where the archive's calibration has the
    camera, else the rig config's nominal geometry."""
    if imported_normtextures(archive.plan):
        return SlotCamera(None, "imported normtextures: no camera to place")
    step, camera_id = slot.captures[0]
    record = next(r for r in archive.step_table() if r.index == step)
    if rig_kind(config).posed_camera(config, camera_id, record.actuators) is not None:
        return SlotCamera(None, "the rig poses the camera anew at every step: not placed per slot")
    turntable = record.actuators.get("turntable_deg", 0.0)
    lens = frame_camera(archive, config, camera_id, turntable)
    calibration = archive_calibration(archive)
    if calibration is not None and calibration.camera(camera_id) is not None:
        source = f"calibrated cameras, {calibration_source(calibration, 'cameras')}"
    else:
        source = "the rig config's camera geometry (nominal)"
    return SlotCamera(lens.center, source)


def per_texel_views(
    model: CompressedBTF,
    cameras: list[SlotCamera],
    valid: np.ndarray,
    radiometry: Radiometry,
    *,
    sample_mm: float,
    components: int,
) -> tuple[CompressedBTF, Radiometry]:
    """The model with every texel moved onto the nominal views (``texel_resampling``)
    and recompressed at ``components``, and the record of what was done; the model as
    it is, with the reason in ``radiometry.skipped["view"]``, where it cannot be.

    ``cameras``: each slot's (:func:`slot_camera`); ``valid``: (S,) bool, slots with data.
    """
    slots = np.flatnonzero(valid)
    unplaced = sorted({c.source for j, c in enumerate(cameras) if valid[j] and c.centre_mm is None})
    why = None
    if unplaced:
        why = "; ".join(unplaced)
    elif len(slots) < 3:
        why = f"{len(slots)} view slot(s) with data: no hull of views to resample in"
    if why is None:
        n = model.mean.shape[1]
        own = np.stack([texel_directions(cameras[j].centre_mm, sample_mm, n) for j in slots])
        try:
            plan = texel_resampling(model.view_dirs_deg[slots], own)
        except ValueError as err:  # the views on one great circle
            why = f"the view slots span no hull ({err})"
    if why is not None:
        skipped = radiometry.skipped | {"view": f"{why}: each texel keeps its slot's nominal view"}
        return model, replace(radiometry, skipped=skipped)
    model = _resampled(model, slots, plan, components)
    sources = sorted({cameras[j].source for j in slots})
    skipped = dict(radiometry.skipped)
    flagged = int(plan.outside.sum())
    if flagged:
        worst = float(plan.turn_deg[plan.outside].max())
        skipped["view"] = (
            f"{flagged} of {plan.outside.size} texel views outside the hull of the views "
            f"that texel was measured at: kept as measured (up to {worst:.1f}° off)"
        )
    sources = radiometry.sources | {"view": "; ".join(sources)}
    return model, replace(radiometry, sources=sources, skipped=skipped)


def _slot_values(model: CompressedBTF, j: int) -> np.ndarray:
    """(lights, n, n, C) float32: every light's normtexture of slot ``j``."""
    basis = model.basis[j].astype(np.float32)
    values = np.einsum("lk,k...->l...", model.weights[j].astype(np.float32), basis)
    return values + model.mean[j].astype(np.float32)


def _resampled(model: CompressedBTF, slots, plan: TexelResampling, components: int):
    mean, basis, weights = model.mean.copy(), model.basis.copy(), model.weights.copy()
    singular, rank = model.singular_values.copy(), model.rank.copy()
    for j, slot in enumerate(slots):
        needed = {int(k) for k in np.unique(plan.indices[j])}
        view = compress_view(blended(plan, j, {k: _slot_values(model, slots[k]) for k in needed}),
                             components=components)  # fmt: skip
        mean[slot], basis[slot], weights[slot] = view.mean, view.basis, view.weights
        singular[slot], rank[slot] = view.singular_values, view.rank
    return replace(model, mean=mean, basis=basis, weights=weights, singular_values=singular,
                   rank=rank)  # fmt: skip
