"""The exact MDF of a sample, by ray casting its relief (trimesh): the MDF the
renderer's checks against the ray-cast truth give their materials."""

from __future__ import annotations

import numpy as np
import trimesh

from processing.mdf import Reason
from rig.geometry import direction_vector, texel_centers_mm
from rig.material import UNSEEN, Mdf

__all__ = ["ray_cast_mdf"]

#: rays start this far above the reference plane (mm), so a relief touching it is still met
_ABOVE_MM = 1e-4


def ray_cast_mdf(
    relief: trimesh.Trimesh, view_dirs_deg, *, sample_mm: float, n: int, source: str
) -> Mdf:
    """D_v(x, y) on the n × n texel grid (``rig.geometry.texel_centers_mm``) at each view.

    Parameters
    ----------
    relief : trimesh.Trimesh
        The sample's surface in its frame (mm, z ≤ 0 under the reference plane z = 0),
        tiled around it far enough that slanted rays leaving the sample's square still
        meet a neighbour's relief.
    view_dirs_deg : (n_views, 2) array
        (θ, φ) of the view slots, degrees, sample frame.
    sample_mm : float
    n : int
    source : str
        What the ``attrs`` say the MDF came from.

    Returns
    -------
    Mdf
        The distance from (x, y, 0) along −v to the first hit (seed 001 §3), −1 (unseen,
        reason UNLIT) where the ray meets nothing.
    """
    views = np.asarray(view_dirs_deg, np.float64)
    xy = texel_centers_mm(sample_mm, n).reshape(-1, 2)
    origins = np.column_stack([xy, np.full(len(xy), _ABOVE_MM)])
    distance = np.full((len(views), n * n), UNSEEN, np.float32)
    for slot, view in enumerate(views):
        v = direction_vector(*view)
        down = np.broadcast_to(-v, origins.shape)
        hits, rays, _ = relief.ray.intersects_location(origins, down, multiple_hits=False)
        t = np.linalg.norm(hits - origins[rays], axis=1)
        distance[slot, rays] = np.maximum(t - _ABOVE_MM / v[2], 0.0)
    shape = (len(views), n, n)
    seen = (distance >= 0).reshape(shape)
    return Mdf(
        distance.reshape(shape), views.astype(np.float32),
        np.where(seen, Reason.OK, Reason.UNLIT).astype(np.uint8), seen.astype(np.uint8),
        attrs={"source": source},
    )  # fmt: skip
