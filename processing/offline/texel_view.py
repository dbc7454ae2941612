"""Per-texel view directions of a perspective camera, and the BTF resampled onto the plan's views.

A camera 800 mm from a 100 mm sample sees each texel from its own direction:
the ray from the texel to the camera's centre turns by up to ±3.6° across the
sample. A view slot's normtexture therefore holds, at texel t, the BTF at t's
own view direction v_t, not at the slot's nominal one. This module places
every slot's camera (its calibrated centre in the sample frame, else the rig
config's nominal one), gives each texel its own direction per slot, and
resamples each texel onto the plan's grid: the value at slot j's nominal
direction is the barycentric blend, on the sphere, of the texel's own measured
directions of the triangle that holds it (the triangulation of the nominal
directions, seed 000 eq. (5), with the texel's directions as its corners).

Where a texel's own directions do not surround the nominal one (outside the
hull of what that texel was measured at: the holding triangle reaches below the
horizon through the triangulation's mirror, or a weight is negative), nothing
is invented: the texel keeps its own measurement and is counted as flagged.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from processing.btf import CompressedBTF, compress_view
from processing.offline.radiometry import calibration_source
from processing.offline.runner import archive_calibration, frame_camera
from rig.archive import Archive
from rig.config import RigConfig
from rig.geometry import direction_vector, spherical_triangulation, texel_centers_mm
from rig.interchange import imported_normtextures
from rig.kinds import rig_kind
from rig.material import Radiometry

__all__ = [
    "SlotCamera",
    "ViewResampling",
    "per_texel_views",
    "slot_camera",
    "texel_view_vectors",
    "view_resampling",
]

#: Weights above −this count as inside a triangle (rounding on its edges).
_EDGE_TOL = 1e-9


@dataclass(frozen=True)
class ViewResampling:
    """How each texel of each slot is blended from the texel's own measured views.

    indices : (S, n, n, 3) int — slots blended (positions in the valid slots)
    weights : (S, n, n, 3) float64 — their weights, summing to 1
    outside : (S, n, n) bool — the nominal direction is outside the texel's own hull:
        weight 1 on its own slot (kept as measured)
    turn_deg : (S, n, n) float64 — angle between the texel's own and the nominal direction
    """

    indices: np.ndarray
    weights: np.ndarray
    outside: np.ndarray
    turn_deg: np.ndarray


def texel_view_vectors(centre_mm: np.ndarray, sample_mm: float, size: int) -> np.ndarray:
    """(size, size, 3) unit vectors from each texel centre (on z = 0) to a camera
    centre ``centre_mm`` (3,), sample frame, mm."""
    points = np.concatenate([texel_centers_mm(sample_mm, size), np.zeros((size, size, 1))], -1)
    rays = np.asarray(centre_mm, dtype=np.float64) - points
    return rays / np.linalg.norm(rays, axis=-1, keepdims=True)


def view_resampling(nominal_deg: np.ndarray, own: np.ndarray) -> ViewResampling:
    """Blend weights that move every texel's measurements onto the nominal views.

    Parameters
    ----------
    nominal_deg : (S, 2) the slots' nominal (θ, φ) view directions, degrees, S ≥ 3
        not on one great circle
    own : (S, n, n, 3) unit vectors, each texel's own view direction per slot
        (:func:`texel_view_vectors`), above the horizon

    Returns
    -------
    ViewResampling
    """
    nominal = direction_vector(nominal_deg[:, 0], nominal_deg[:, 1])
    mesh = spherical_triangulation(nominal)  # the topology: the nominal table's
    owner = mesh.owner  # (T, 3) slot of each corner
    mirrored = mesh.corners[..., 2] < 0.0  # (T, 3) corners below the horizon
    flip = np.where(mirrored[..., None], np.array([1.0, 1.0, -1.0]), 1.0)  # (T, 3, 3)
    # each texel's triangles: its own directions at the nominal corners (mirrored alike)
    corners = own[owner] * flip[:, :, None, None, :]  # (T, 3, n, n, 3)
    corners = np.moveaxis(corners, (2, 3), (0, 1))  # (n, n, T, 3 corners, 3 xyz)
    inverse = np.linalg.pinv(np.swapaxes(corners, -1, -2))  # w = inverse · q
    n = own.shape[1]
    slots = len(nominal)
    indices = np.empty((slots, n, n, 3), np.int64)
    weights = np.empty((slots, n, n, 3))
    outside = np.empty((slots, n, n), bool)
    for j in range(slots):
        w = inverse @ nominal[j]  # (n, n, T, 3)
        best = np.argmax(w.min(axis=-1), axis=-1)  # (n, n) the triangle holding it
        wq = np.take_along_axis(w, best[..., None, None], axis=2)[:, :, 0]
        below = (mirrored[best] & (wq > _EDGE_TOL)).any(axis=-1)
        out = below | (wq.min(axis=-1) < -_EDGE_TOL)
        wq = np.clip(wq, 0.0, None)
        wq /= wq.sum(axis=-1, keepdims=True)
        indices[j] = np.where(out[..., None], j, owner[best])
        weights[j] = np.where(out[..., None], np.array([1.0, 0.0, 0.0]), wq)
        outside[j] = out
    turn = np.degrees(np.arccos(np.clip(np.einsum("snmk,sk->snm", own, nominal), -1.0, 1.0)))
    return ViewResampling(indices, weights, outside, turn)


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
    """The model with every texel moved onto the nominal views (:func:`view_resampling`)
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
        own = np.stack([texel_view_vectors(cameras[j].centre_mm, sample_mm, n) for j in slots])
        try:
            plan = view_resampling(model.view_dirs_deg[slots], own)
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


def _resampled(model: CompressedBTF, slots, plan: ViewResampling, components: int):
    mean, basis, weights = model.mean.copy(), model.basis.copy(), model.weights.copy()
    singular, rank = model.singular_values.copy(), model.rank.copy()
    for j, slot in enumerate(slots):
        needed = {int(k) for k in np.unique(plan.indices[j])}
        values = {k: _slot_values(model, slots[k]) for k in needed}
        blend = np.zeros_like(values[j])
        for c in range(3):
            for k in needed:
                w = np.where(plan.indices[j, ..., c] == k, plan.weights[j, ..., c], 0.0)
                blend += values[k] * w[None, :, :, None].astype(np.float32)
        view = compress_view(blend, components=components)
        mean[slot], basis[slot], weights[slot] = view.mean, view.basis, view.weights
        singular[slot], rank[slot] = view.singular_values, view.rank
    return replace(model, mean=mean, basis=basis, weights=weights, singular_values=singular,
                   rank=rank)  # fmt: skip
