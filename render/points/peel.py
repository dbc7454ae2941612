"""Mesostructure silhouettes by front-to-back depth peeling (seed 001 §4.1, Fig. 7).

A ray that enters the object at a front face p_f and leaves it at a back face
p_b meets the mesostructure under the surface when d_f + d_b ≤ |p_f − p_b|,
with d = s · D(x, y, v) the MDF at each face (v pointing away from the surface,
s = tile_mm / sample_mm the texture scale). Each peeling pass handles one such
interval per pixel, nearest first:

1. back faces beyond the previous layer's back face (``Zpeel_now``), depth test
   on their own buffer: the nearest is this layer's p_b; its ray distance t_b
   and d_b go to ``Zpeel_next``;
2. front faces between ``Zpeel_now`` and t_b, depth test on the frame's depth
   buffer: p_f is kept (its depth written) where t_f + d_f ≤ t_b − d_b, and the
   hit mask set;
3. the two peel buffers swap.

The hit mask plays the stencil's part (moderngl has no stencil operations):
the back faces of later layers skip pixels already hit, and the frame's depth
buffer, holding the nearer hit, keeps their front faces out. After the passes
the depth buffer holds, per pixel, the front face whose ray met the
mesostructure (1.0 where none did), and the renderer shades with the depth
test ``==``: only those faces, once each.

The method assumes closed objects: on an open mesh a ray's front and back
faces need not bound a solid (a sheet seen through a fold behind it would be
cut away), so :func:`mdf_silhouettes` draws an open mesh — one with edges
that bound a single face once coincident vertices are merged
(:func:`open_edges`) — without MDF silhouettes and logs a warning saying so.
A front face with no back face behind it (more layers than passes) has
nothing to pair with and is kept as the mesh's own surface.
"""

from __future__ import annotations

import logging

import moderngl
import numpy as np

from render._errors import RenderError
from render.core.gl import vertex_array
from render.core.programs import build_program
from render.core.units import TextureUnits
from render.points.mdf import MdfTexture

__all__ = ["MAX_PEEL", "SilhouettePeel", "mdf_silhouettes", "open_edges"]

_log = logging.getLogger(__name__)

#: Most peeling passes a renderer accepts.
MAX_PEEL = 8
_NONE = 1e30  # "no back face" / "before the first layer" in the peel buffers


def open_edges(mesh) -> int:
    """Edges used by exactly one face once vertices at the same position (mm,
    to 1e-4 of the mesh's size) are merged: 0 for a closed mesh whose UV seams
    split its vertices."""
    positions = np.asarray(mesh.positions, np.float64)
    extent = max(float(np.ptp(positions, axis=0).max()), 1e-9)
    keys = np.round(positions / (extent * 1e-4)).astype(np.int64)
    _, welded = np.unique(keys, axis=0, return_inverse=True)
    faces = welded.reshape(-1)[np.asarray(mesh.faces, np.int64)]
    faces = faces[(faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2])
                  & (faces[:, 0] != faces[:, 2])]  # fmt: skip
    edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    return int((counts == 1).sum())


class _Buffers:
    """The peel buffers of one frame size: two (t, d) float textures with the back
    faces' depth buffer, and the hit mask drawn with the frame's depth buffer."""

    def __init__(self, ctx: moderngl.Context, size: tuple[int, int], depth) -> None:
        self.peel = [ctx.texture(size, 2, dtype="f4") for _ in range(2)]
        self.back_depth = ctx.depth_renderbuffer(size)
        self.mask = ctx.texture(size, 1, dtype="f1")
        for texture in (*self.peel, self.mask):
            texture.filter = (moderngl.NEAREST, moderngl.NEAREST)
        self.back = [ctx.framebuffer([texture], self.back_depth) for texture in self.peel]
        self.front = ctx.framebuffer([self.mask], depth)

    def release(self) -> None:
        for obj in (*self.back, self.front, *self.peel, self.back_depth, self.mask):
            obj.release()


class SilhouettePeel:
    """The peeling passes of one renderer's mesh and MDF.

    Parameters
    ----------
    ctx : moderngl.Context
    vbo, ibo : moderngl.Buffer
        The mesh buffers (``render.core.gl.mesh_buffers``).
    mdf : MdfTexture
        The renderer's (it releases it).
    passes : int
        Peeling passes, 1 … :data:`MAX_PEEL` (seed 001 lets the user choose).
    texture_scale : float
        s = tile_mm / sample_mm, mm of the scene per mm of the sample.
    uv_scale : float
        1 / tile_mm, as the surface shader's.
    """

    def __init__(self, ctx, vbo, ibo, mdf: MdfTexture, *, passes: int, texture_scale: float,
                 uv_scale: float) -> None:  # fmt: skip
        self.ctx, self.mdf, self.passes = ctx, mdf, int(passes)
        self.programs = {}
        for back in (1, 0):
            program = build_program(
                ctx, "surface.vert", "peel.frag", defines={**mdf.defines(), "BACK_FACES": back}
            )
            program["texture_scale"].value = float(texture_scale)
            program["uv_scale"].value = float(uv_scale)
            self.programs[back] = (program, vertex_array(ctx, program, vbo, ibo))
        self._buffers: dict[tuple[int, tuple[int, int]], _Buffers] = {}

    def draw(self, camera, view_proj: bytes, depth, units: TextureUnits) -> None:
        """Fill the depth renderbuffer ``depth`` (of ``camera.size``) with the front
        faces whose rays meet the mesostructure; 1.0 elsewhere. The textures go on
        the units of their samplers in ``units`` (the renderer's)."""
        key = (depth.glo, camera.size)
        if key not in self._buffers:
            self._buffers[key] = _Buffers(self.ctx, camera.size, depth)
        buffers = self._buffers[key]
        for program, _ in self.programs.values():
            program["view_proj"].write(view_proj)
            program["orthographic"].value = camera.fov_deg is None
            program["eye"].value = tuple(camera.eye)
            program["toward_camera"].value = tuple(-camera.forward)
        back_faces, front_faces = self.programs[1][0], self.programs[0][0]
        units.use("mdf_distance", self.mdf.distance, back_faces, front_faces)
        units.use("mdf_view_cells", self.mdf.view_cells, back_faces, front_faces)
        ctx = self.ctx
        buffers.back[0].use()
        buffers.back[0].clear(-_NONE, 0.0, 0.0, 0.0)  # before the first layer
        buffers.front.use()
        buffers.front.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
        ctx.enable_only(moderngl.DEPTH_TEST | moderngl.CULL_FACE)
        ctx.depth_func = "<"
        for k in range(self.passes):
            now, nxt = buffers.peel[k % 2], buffers.back[(k + 1) % 2]
            units.use("peel_now", now, back_faces, front_faces)
            units.use("hit_mask", buffers.mask, back_faces)
            nxt.use()
            nxt.clear(_NONE, 0.0, 0.0, 0.0, depth=1.0)
            ctx.cull_face = "front"
            self.programs[1][1].render(moderngl.TRIANGLES)
            units.use("peel_next", buffers.peel[(k + 1) % 2], front_faces)
            buffers.front.use()
            ctx.cull_face = "back"
            self.programs[0][1].render(moderngl.TRIANGLES)
        ctx.cull_face = "back"
        ctx.enable_only(moderngl.DEPTH_TEST)

    def release(self) -> None:
        for buffers in self._buffers.values():
            buffers.release()
        self._buffers.clear()
        for program, vao in self.programs.values():
            vao.release()
            program.release()
        self.programs.clear()


def mdf_silhouettes(ctx, mesh, vbo, ibo, texture: MdfTexture | None, *, peel: int,
                    texture_scale: float, uv_scale: float,
                    asked: bool = True) -> SilhouettePeel | None:  # fmt: skip
    """The depth peeling of the MDF ``texture`` on ``mesh`` (a renderer's buffers;
    ``texture_scale``, ``uv_scale`` as :class:`SilhouettePeel`'s), or None: no
    texture (drawn without the MDF), or an open mesh (a warning where the MDF was
    ``asked`` for, else an info line: the MDF only came with the material).

    Raises
    ------
    RenderError
        ``peel`` not in 1…:data:`MAX_PEEL`.
    """
    if not (isinstance(peel, int | np.integer) and 1 <= peel <= MAX_PEEL):
        raise RenderError(f"peel = {peel!r}: valid are 1…{MAX_PEEL} passes")
    if texture is None:
        return None
    holes = open_edges(mesh)
    if holes:
        _log.log(
            logging.WARNING if asked else logging.INFO,
            "mesh %r is open (%d edges bound one face only) and MDF silhouettes need a closed "
            "object: drawn without them, with the mesh's own outline", mesh.name, holes,
        )  # fmt: skip
        return None
    return SilhouettePeel(
        ctx, vbo, ibo, texture, passes=peel, texture_scale=texture_scale, uv_scale=uv_scale
    )
