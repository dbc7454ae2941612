"""Which archived capture fills which (view slot, light) of the BTF.

A session's BTF steps each record the view direction of every camera and the
light direction; :func:`view_slots` groups the (step, camera) captures into
view slots (same view direction) and orders each slot's lights the same way,
so slot j's normtextures can be stacked as (n_lights, N, N, C) and handed to
:func:`~processing.btf.compress_view`.

A step whose rig could not reach the pair it was asked for records directions
displaced from it (the Bonn lab's retro-reflection pairs: its rail cannot put
the camera in the lamp's beam, ``rig.bonn.displaced_by_deg``). Such a capture
fills the grid cell nearest its recorded view and light within the
displacement, and is listed in ``SlotTable.displaced`` with the directions it
was measured at; the grid itself is built from the steps that hit their pair.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from processing.btf._errors import BtfError
from rig.archive import StepRecord
from rig.geometry import angular_distance_deg, direction_vector

__all__ = ["Displaced", "SlotTable", "view_slots"]


@dataclass(frozen=True)
class Displaced:
    """A capture filed under a grid cell it was not measured at: the directions it was."""

    slot: int
    light: int
    step: int
    camera: str
    view_deg: tuple[float, float]
    light_deg: tuple[float, float]


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
    displaced : tuple of Displaced
        The cells filled by a capture measured off them, with where it was.
    """

    view_dirs_deg: np.ndarray
    light_dirs_deg: np.ndarray
    steps: np.ndarray
    cameras: np.ndarray
    displaced: tuple[Displaced, ...] = ()


def _index(table: list[tuple[float, float]], direction, tol_deg: float) -> int:
    """The entry of ``table`` nearest ``direction`` within ``tol_deg``, else a new one."""
    if table:
        known = direction_vector(*np.array(table).T)
        gaps = angular_distance_deg(known, direction_vector(*direction))
        nearest = int(np.argmin(gaps))
        if gaps[nearest] <= tol_deg:
            return nearest
    table.append(tuple(float(a) for a in direction))
    return len(table) - 1


def view_slots(
    steps: list[StepRecord],
    *,
    kind: str = "btf",
    tol_deg: float = 0.5,
    gaps: bool = False,
    displaced_by_deg: Mapping[int, float] | None = None,
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
    displaced_by_deg : mapping step index → deg, optional
        Steps whose recorded directions each lie up to that far from the pair
        they were asked for (``RigKind.displaced_by_deg``); missing or 0: on it.

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
    displaced_by_deg = displaced_by_deg or {}
    view_deg: list[tuple[float, float]] = []
    light_deg: list[tuple[float, float]] = []
    cells: dict[tuple[int, int], tuple[int, str]] = {}
    displaced = []
    ours = [s for s in steps if s.kind == kind]
    # the steps on their pair build the grid first; the displaced then join its nearest cells
    for step in sorted(ours, key=lambda s: displaced_by_deg.get(s.index, 0.0) > 0):
        if step.light_deg is None:
            raise BtfError(f"step {step.index} ({kind}) records no light direction")
        reach = tol_deg + displaced_by_deg.get(step.index, 0.0)
        li = _index(light_deg, step.light_deg, reach)
        for camera in step.cameras:
            if camera not in step.views_deg:
                raise BtfError(f"step {step.index} records no view direction for {camera!r}")
            vj = _index(view_deg, step.views_deg[camera], reach)
            if (vj, li) in cells:
                first = cells[(vj, li)][0]
                raise BtfError(
                    f"view {view_deg[vj]} under light {light_deg[li]} captured twice "
                    f"(steps {first} and {step.index}); keep one or widen the sampling"
                )
            cells[(vj, li)] = (step.index, camera)
            view = step.views_deg[camera]
            off = max(_gap_deg(view, view_deg[vj]), _gap_deg(step.light_deg, light_deg[li]))
            if off > tol_deg:
                displaced.append(
                    Displaced(vj, li, step.index, camera, tuple(view), tuple(step.light_deg))
                )
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
        camera_table.astype(str), tuple(sorted(displaced, key=lambda d: (d.slot, d.light))),
    )  # fmt: skip


def _gap_deg(a, b) -> float:
    return float(angular_distance_deg(direction_vector(*a), direction_vector(*b)))
