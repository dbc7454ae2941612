"""Which archived capture fills which (view slot, light) of the BTF.

A session's BTF steps each record the view direction of every camera and the
light direction; :func:`view_slots` groups the (step, camera) captures into
view slots (same view direction) and orders each slot's lights the same way,
so slot j's normtextures can be stacked as (n_lights, N, N, C) and handed to
:func:`~processing.btf.compress_view`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from processing.btf._errors import BtfError
from rig.archive import StepRecord
from rig.geometry import angular_distance_deg, direction_vector

__all__ = ["SlotTable", "view_slots"]


@dataclass(frozen=True)
class SlotTable:
    """The layout of a measured BTF in an archive.

    Attributes
    ----------
    view_dirs_deg : (n_views, 2) float64
        (θ, φ) of each view slot, sample frame, in order of first capture.
    light_dirs_deg : (n_lights, 2) float64
        (θ, φ) of each light, shared by every slot, in order of first capture.
    steps : (n_views, n_lights) int64
        Step index of the capture of slot j under light i.
    cameras : (n_views, n_lights) str
        Camera id of that capture (a slot may be served by different cameras).
    """

    view_dirs_deg: np.ndarray
    light_dirs_deg: np.ndarray
    steps: np.ndarray
    cameras: np.ndarray


def _index(table: list[np.ndarray], direction, tol_deg: float) -> int:
    v = direction_vector(*direction)
    for i, known in enumerate(table):
        if angular_distance_deg(known, v) <= tol_deg:
            return i
    table.append(v)
    return len(table) - 1


def view_slots(
    steps: list[StepRecord], *, kind: str = "btf", tol_deg: float = 0.5, gaps: bool = False
) -> SlotTable:
    """Group the ``kind`` steps' captures into view slots × lights.

    Parameters
    ----------
    steps : list of StepRecord
        ``archive.step_table()``; steps of other kinds are skipped.
    kind : str
        Step kind of the BTF captures.
    tol_deg : float
        Directions closer than this are the same slot (or light).
    gaps : bool
        Accept (view, light) pairs that were not captured: their step is −1
        and their camera ``""`` (an imported partial data set).

    Returns
    -------
    SlotTable

    Raises
    ------
    BtfError
        No capture of that kind, a capture without a light, a (slot, light)
        captured twice, or (unless ``gaps``) a slot missing a light the
        others have — each named by its directions.
    """
    if not tol_deg > 0:
        raise BtfError(f"tol_deg = {tol_deg}: must be > 0")
    views: list[np.ndarray] = []
    lights: list[np.ndarray] = []
    view_deg: list[tuple[float, float]] = []
    light_deg: list[tuple[float, float]] = []
    cells: dict[tuple[int, int], tuple[int, str]] = {}
    for step in steps:
        if step.kind != kind:
            continue
        if step.light_deg is None:
            raise BtfError(f"step {step.index} ({kind}) records no light direction")
        li = _index(lights, step.light_deg, tol_deg)
        if li == len(light_deg):
            light_deg.append(tuple(step.light_deg))
        for camera in step.cameras:
            if camera not in step.views_deg:
                raise BtfError(f"step {step.index} records no view direction for {camera!r}")
            vj = _index(views, step.views_deg[camera], tol_deg)
            if vj == len(view_deg):
                view_deg.append(tuple(step.views_deg[camera]))
            if (vj, li) in cells:
                first = cells[(vj, li)][0]
                raise BtfError(
                    f"view {view_deg[vj]} under light {light_deg[li]} captured twice "
                    f"(steps {first} and {step.index}); keep one or widen the sampling"
                )
            cells[(vj, li)] = (step.index, camera)
    if not cells:
        raise BtfError(f"no steps of kind {kind!r} with captures")
    n_views, n_lights = len(view_deg), len(light_deg)
    step_table = np.full((n_views, n_lights), -1, np.int64)
    camera_table = np.full((n_views, n_lights), "", dtype=object)
    for (vj, li), (index, camera) in cells.items():
        step_table[vj, li], camera_table[vj, li] = index, camera
    missing = np.argwhere(step_table < 0)
    if len(missing) and not gaps:
        vj, li = missing[0]
        raise BtfError(
            f"{len(missing)} (view, light) pairs were not captured, e.g. view {view_deg[vj]} "
            f"under light {light_deg[li]}; every view slot needs the same lights"
        )
    return SlotTable(
        np.array(view_deg, np.float64), np.array(light_deg, np.float64), step_table,
        camera_table.astype(str),
    )  # fmt: skip
