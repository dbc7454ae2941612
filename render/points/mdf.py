"""The mesostructure distance function on the GPU (seed 001 §4–§5).

The material's MDF (``rig.material.Mdf``) holds, per view slot v and texel
(x, y), the distance D_v(x, y) in mm along the view ray from the reference
plane (the sample's top, z = 0) down to the first mesostructure surface, −1
where the laser never saw it. The renderer keeps it as one float32 texture
array, a layer per view slot (the view directions packed in the third
dimension, seed 001 §5), read bilinearly over texels (repeating, like the
BTF) and blended over view slots with the BTF's own neighbourhoods: the same
:func:`render.core.lookup.build_lookup` candidate grids and the same shader
functions (``shaders/directions.glsl``), so D at a view between slots mixes
the slots the BTF mixes there, with the same weights.

Before upload the table is made complete and bounded (:func:`mdf_table`):

- **Unseen texels** (−1) are *filled along the view axis*: a texel unseen in
  view v takes the depth below the plane, h = D_u · cos θ_u, that the nearest
  view slot u (by angle) which saw that texel found, seen from v:
  D_v = h / cos θ_v. Laser shadows and occlusions leave a texel unseen in some
  views while others saw its surface; treating it as the base depth instead
  would punch see-through holes into silhouettes wherever the scanner merely
  missed. A texel no view saw has nothing to copy and takes the base depth,
  d_max / cos θ_v (d_max the deepest seen point, max h): the ray passes
  through the layer. An MDF that is all unseen thus has d_max = 0 and D = 0
  everywhere: the silhouettes are the mesh's own.
- **Grazing views**: D grows as 1 / cos θ towards the horizon. Every value is
  clamped to d_max / cos 80° (5.76 · d_max, :data:`GRAZING_DEG`); a seen value
  never exceeds d_max / cos θ_v, so only slots beyond 80° are cut. Blending
  between slots never leaves their range, so the shader's D is bounded by the
  largest slot value at any view, the horizon included.

Mipmaps are not built: an average of distances is no ray's distance, and a
minified MDF would blur the silhouette it is there to cut.
"""

from __future__ import annotations

from dataclasses import dataclass

import moderngl
import numpy as np

from render._errors import RenderError
from render.core.lookup import DirectionLookup, build_lookup
from render.core.textures import lookup_texture
from rig.geometry import (
    angular_distance_deg,
    barycentric_weights,
    direction_vector,
    nearest_directions,
)
from rig.material import Mdf

__all__ = ["GRAZING_DEG", "MdfTable", "MdfTexture", "mdf_reference", "mdf_table", "upload_mdf"]

#: Views beyond this polar angle get the clamp of this one.
GRAZING_DEG = 80.0


@dataclass(frozen=True)
class MdfTable:
    """A complete, bounded MDF ready for the GPU.

    Attributes
    ----------
    distance_mm : (n_views, N, N) float32
        D_v on the texel grid (row 0 at +y, ``rig.geometry.texel_centers_mm``),
        every texel ≥ 0 and finite: unseen ones filled, grazing ones clamped.
    view_vectors : (n_views, 3) float64
        Unit view directions of the slots, sample frame.
    depth_mm : float
        d_max, the deepest seen mesostructure point below the reference plane
        (max of D · cos θ over seen texels; 0 if none was seen).
    filled : int
        (view, texel) values that were unseen and filled from another view.
    never_seen : int
        Texels no view saw (they take the base depth).
    """

    distance_mm: np.ndarray
    view_vectors: np.ndarray
    depth_mm: float
    filled: int
    never_seen: int

    @property
    def size(self) -> int:
        return self.distance_mm.shape[1]


def mdf_table(mdf: Mdf) -> MdfTable:
    """The MDF with unseen texels filled and grazing values clamped (see the module)."""
    views = direction_vector(mdf.view_dirs_deg[:, 0], mdf.view_dirs_deg[:, 1])
    cos_theta = np.maximum(views[:, 2], 0.0)[:, None, None]
    distance = np.asarray(mdf.distance_mm, np.float64)
    seen = distance >= 0
    depth = np.where(seen, distance * cos_theta, 0.0)  # h = D cos θ below the plane
    depth_max = float(depth.max()) if seen.any() else 0.0
    angles = angular_distance_deg(views[:, None, :], views[None, :, :])
    filled_depth = depth.copy()
    seen_anywhere = seen.any(axis=0)
    for v in range(len(views)):
        missing = ~seen[v] & seen_anywhere
        for u in np.argsort(angles[v], kind="stable")[1:]:
            if not missing.any():
                break
            take = missing & seen[u]
            filled_depth[v][take] = depth[u][take]
            missing &= ~take
        filled_depth[v][~seen_anywhere] = depth_max  # seen by no view: the base
    slant = np.maximum(cos_theta, np.cos(np.deg2rad(GRAZING_DEG)))  # h ≤ d_max: the clamp
    return MdfTable(
        distance_mm=np.ascontiguousarray(filled_depth / slant, np.float32),
        view_vectors=views,
        depth_mm=depth_max,
        filled=int((~seen).sum()),
        never_seen=int((~seen_anywhere).sum()),
    )


def _view_weights(table: MdfTable, view_local: np.ndarray, method: str):
    """(m, k) slot indices and weights at each view, as the shader blends them."""
    q = np.array(view_local, np.float64)
    q[:, 2] = np.maximum(q[:, 2], 0.0)  # below the horizon: laid onto it
    if method == "barycentric":
        found = barycentric_weights(table.view_vectors, q)
    elif method in ("nearest", "nearest4"):
        k = 1 if method == "nearest" else min(4, len(table.view_vectors))
        found = nearest_directions(table.view_vectors, q, k=k)
    else:
        raise RenderError(f"view_method = {method!r}: valid are nearest, nearest4, barycentric")
    return found.indices, found.weights


def mdf_reference(table: MdfTable, st, view_local, *, method: str = "nearest4") -> np.ndarray:
    """What the shader's ``mdf_distance_mm`` gives, in numpy (float64).

    Parameters
    ----------
    table : MdfTable
    st : (m, 2) array
        Texture coordinates (repeats of the sample; (0, 0) its −x, −y corner).
    view_local : (m, 3) array
        Unit view directions in the tangent frame, pointing away from the surface.
    method : {"nearest4", "barycentric", "nearest"}
        The view blend, as the renderer's ``view_method``.

    Returns
    -------
    (m,) float64
        D in mm of the sample: bilinear over texels (GL's rule, repeating) in
        each blended view slot, weighted as ``rig.geometry`` weights the slots.
    """
    st = np.asarray(st, np.float64).reshape(-1, 2)
    n = table.size
    # GL texel centres at (i + ½)/n; texture row j is the grid's row n − 1 − j.
    x = st[:, 0] * n - 0.5
    y = st[:, 1] * n - 0.5
    x0, y0 = np.floor(x), np.floor(y)
    fx, fy = x - x0, y - y0
    cols = np.mod(np.stack([x0, x0 + 1]), n).astype(np.int64)
    rows = n - 1 - np.mod(np.stack([y0, y0 + 1]), n).astype(np.int64)
    index, weight = _view_weights(table, np.asarray(view_local).reshape(-1, 3), method)
    out = np.zeros(len(st))
    for j in range(index.shape[1]):
        slot = table.distance_mm[index[:, j]].astype(np.float64)  # (m, N, N)
        m = np.arange(len(st))
        texel = (
            (1 - fx) * (1 - fy) * slot[m, rows[0], cols[0]]
            + fx * (1 - fy) * slot[m, rows[0], cols[1]]
            + (1 - fx) * fy * slot[m, rows[1], cols[0]]
            + fx * fy * slot[m, rows[1], cols[1]]
        )
        out += weight[:, j] * texel
    return out


@dataclass
class MdfTexture:
    """The MDF on the GPU: ``distance`` (N, N, n_views) float32 texture array and
    the view lookup ``view_cells``; bind them as ``mdf_distance`` and ``mdf_view_cells``
    of a program compiled with :meth:`defines` and ``shaders/mdf.glsl``."""

    table: MdfTable
    lookup: DirectionLookup
    distance: moderngl.TextureArray
    view_cells: moderngl.TextureArray

    def defines(self) -> dict[str, int]:
        """The shader constants of ``mdf.glsl``."""
        return {
            "MDF_VIEW_METHOD": self.lookup.code,
            "MDF_VIEW_K": self.lookup.k,
            "MDF_VIEW_CANDIDATES": self.lookup.length,
        }

    def release(self) -> None:
        self.distance.release()
        self.view_cells.release()


def upload_mdf(ctx: moderngl.Context, table: MdfTable, *, view_method: str) -> MdfTexture:
    """The texture array of ``table`` and its view lookup for ``view_method``."""
    n_views, n = len(table.distance_mm), table.size
    limit = int(ctx.info["GL_MAX_ARRAY_TEXTURE_LAYERS"])
    if n_views > limit:
        raise RenderError(f"material mdf: {n_views} view slots, this GL allows {limit} layers")
    lookup = build_lookup(table.view_vectors, view_method)
    data = np.ascontiguousarray(table.distance_mm[:, ::-1], np.float32)
    distance = ctx.texture_array((n, n, n_views), 1, data, dtype="f4")
    distance.repeat_x = distance.repeat_y = True
    distance.filter = (moderngl.LINEAR, moderngl.LINEAR)
    return MdfTexture(table, lookup, distance, lookup_texture(ctx, lookup))
