"""Merging displacement images over laser locations, and the MDF of all views.

Seed ``001_…`` section 3.2, "Merging displacement images":

    D_v(x, y) = Σ_i w_i D_{v,l_i}(x, y) / Σ_i w_i   over the i with D_{v,l_i}(x, y) ≠ -1,

with w_i the volume of the tetrahedron formed by the laser source, the camera
and two points on the laser line through the turntable centre
(:func:`~processing.mdf.sheet.tetrahedron_weight`). A texel no location saw
stays -1.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from processing.mdf._errors import MdfError
from processing.mdf._reason import Reason
from processing.mdf.displacement import ScanDisplacement
from rig.camera import PinholeCamera
from rig.geometry import direction_angles
from rig.material import Mdf

__all__ = ["Mdf", "ViewDisplacement", "assemble_mdf", "merge_scans", "view_direction_deg"]


@dataclass(frozen=True)
class ViewDisplacement:
    """D_v: the merged displacement image of one view.

    Attributes
    ----------
    distance : (N, N) float32
        mm along the view ray from (x, y, 0) to the surface; -1 unseen.
    reason : (N, N) uint8
        OK where at least one location gave a value (EDGE if all that did
        were EDGE), otherwise the largest :class:`~processing.mdf.Reason`
        code among the locations.
    count : (N, N) uint8
        Locations that contributed.
    spread_mm : (N, N) float32
        Largest minus smallest contributing value (0 for fewer than two): a
        consistency check between laser locations.
    """

    distance: np.ndarray
    reason: np.ndarray
    count: np.ndarray
    spread_mm: np.ndarray


def merge_scans(scans: Sequence[ScanDisplacement]) -> ViewDisplacement:
    """Weighted merge of the displacement images of one view.

    Parameters
    ----------
    scans : sequence of ScanDisplacement
        One per laser location, same texel grid. Scans with weight 0 never
        contribute.

    Returns
    -------
    ViewDisplacement
    """
    if not scans:
        raise MdfError("merge_scans: no displacement image to merge")
    shapes = {s.distance.shape for s in scans}
    if len(shapes) != 1:
        raise MdfError(f"merge_scans: the scans use different texel grids {sorted(shapes)}")
    weights = np.array([s.weight for s in scans], dtype=np.float64)
    if not np.all(np.isfinite(weights)) or np.any(weights < 0):
        raise MdfError(f"merge_scans: weights must be finite and ≥ 0, got {weights}")
    dist = np.stack([s.distance for s in scans]).astype(np.float64)
    reason = np.stack([s.reason for s in scans])
    valid = (reason <= Reason.EDGE) & (weights[:, None, None] > 0)
    w = np.where(valid, weights[:, None, None], 0.0)
    w_sum = w.sum(axis=0)
    seen = w_sum > 0
    merged = np.where(seen, (w * dist).sum(axis=0) / np.where(seen, w_sum, 1.0), -1.0)
    count = valid.sum(axis=0)
    hi = np.where(valid, dist, -np.inf).max(axis=0)
    lo = np.where(valid, dist, np.inf).min(axis=0)
    spread = np.where(count >= 2, hi - lo, 0.0)
    all_edge = ~(valid & (reason == Reason.OK)).any(axis=0)
    out_reason = np.where(all_edge, Reason.EDGE, Reason.OK).astype(np.uint8)
    out_reason = np.where(seen, out_reason, np.where(valid, 0, reason).max(axis=0))
    return ViewDisplacement(
        distance=merged.astype(np.float32),
        reason=out_reason.astype(np.uint8),
        count=np.minimum(count, 255).astype(np.uint8),
        spread_mm=spread.astype(np.float32),
    )


def view_direction_deg(camera: PinholeCamera) -> np.ndarray:
    """(2,) float64 (θ, φ) in degrees of the view: from the sample centre to the camera."""
    theta, phi = direction_angles(camera.center)
    return np.array([float(theta), float(phi)])


def assemble_mdf(views: Sequence[ViewDisplacement], view_dirs_deg) -> Mdf:
    """Stack merged views into the material's :class:`~rig.material.Mdf`.

    Parameters
    ----------
    views : V × ViewDisplacement
    view_dirs_deg : (V, 2) float
        (θ, φ) of each view, e.g. from :func:`view_direction_deg`.
    """
    dirs = np.asarray(view_dirs_deg, dtype=np.float64)
    if not views or dirs.shape != (len(views), 2) or not np.all(np.isfinite(dirs)):
        raise MdfError(
            f"assemble_mdf: need one finite (θ, φ) per view; got {len(views)} views and "
            f"view_dirs_deg of shape {dirs.shape}"
        )
    shapes = {v.distance.shape for v in views}
    if len(shapes) != 1:
        raise MdfError(f"assemble_mdf: the views use different texel grids {sorted(shapes)}")
    return Mdf(
        distance_mm=np.stack([v.distance for v in views]).astype(np.float32),
        view_dirs_deg=dirs.astype(np.float32),
        reason=np.stack([v.reason for v in views]),
        count=np.stack([v.count for v in views]),
    )
