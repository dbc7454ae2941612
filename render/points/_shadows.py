"""Macro shadows: one depth map per light, side by side in one atlas texture.

A directional light looks at the mesh's bounding sphere with an orthographic
projection that just holds it; a point light with a perspective one (field of
view at most 150°: parts of the scene outside it count as lit). The surface
shader compares against 5×5 bilinear taps (percentage-closer filtering), so
shadow boundaries are soft over a few shadow-map texels.

With a mesostructure depth (``base_depth`` > 0, seed 001 §4.2) each map
holds the depth of the mesostructure's base below every surface instead of
the surface's own (``shaders/shadow_mdf.frag``); the surface shader then
tests the mesostructure point its view ray meets.
"""

from __future__ import annotations

import moderngl
import numpy as np

from render._errors import RenderError
from render.camera import Camera
from render.core.gl import vertex_array
from render.core.programs import build_program
from render.core.units import TextureUnits
from render.lights import PointLight
from render.points.mdf import GRAZING_DEG

__all__ = ["ShadowMaps", "light_camera"]

_MAX_FOV_DEG = 150.0


def light_camera(light, center: np.ndarray, radius: float, size: int) -> Camera:
    """The camera a light sees the bounding sphere (``center``, ``radius``) with."""
    if isinstance(light, PointLight):
        eye = np.asarray(light.position, np.float64)
        distance = float(np.linalg.norm(center - eye))
        if distance <= radius * 1.05:
            fov = _MAX_FOV_DEG
        else:
            fov = min(2.2 * np.rad2deg(np.arcsin(radius / distance)), _MAX_FOV_DEG)
        target = center if distance > 0 else center + np.array([0.0, 0.0, -1.0])
        return Camera.perspective(eye, target, up=(0, 0, 1), fov_deg=fov, size=(size, size))
    eye = center + light.unit_direction * 2.0 * radius
    return Camera.orthographic(eye, center, up=(0, 0, 1), height=2.1 * radius, size=(size, size))


class ShadowMaps:
    """The shadow-map atlas of a frame's lights, drawn from the mesh's buffers."""

    def __init__(
        self, ctx: moderngl.Context, vbo, ibo, *, size: int, base_depth: float = 0.0
    ) -> None:
        """``base_depth``: the mesostructure's depth below the surfaces, scene units (0: none)."""
        if not 16 <= size <= 8192:
            raise RenderError(f"shadow_size = {size}: valid are 16…8192 texels")
        self.ctx, self.size, self.base_depth = ctx, int(size), float(base_depth)
        shaders = ("shadow_mdf.vert", "shadow_mdf.frag") if base_depth > 0 else (
            "depth.vert", "depth.frag")  # fmt: skip
        self.program = build_program(ctx, *shaders)
        if base_depth > 0:
            self.program["base_depth"].value = self.base_depth
            self.program["max_slant"].value = 1.0 / np.cos(np.deg2rad(GRAZING_DEG))
        self.vao = vertex_array(ctx, self.program, vbo, ibo)
        self.atlas: moderngl.Texture | None = None
        self.fbo: moderngl.Framebuffer | None = None
        self.view_proj = np.zeros((0, 4, 4), np.float32)
        self.texel_mm = np.zeros(0, np.float32)

    def _atlas(self, tiles: int) -> None:
        width = self.size * tiles
        if self.atlas is not None and self.atlas.size == (width, self.size):
            return
        self._release_atlas()
        limit = int(self.ctx.info["GL_MAX_TEXTURE_SIZE"])
        if width > limit:
            raise RenderError(
                f"{tiles} shadow maps of {self.size}² need {width} texels, this GL allows {limit}; "
                "use a smaller shadow_size"
            )
        self.atlas = self.ctx.depth_texture((width, self.size))
        self.atlas.compare_func = "<="
        self.atlas.filter = (moderngl.LINEAR, moderngl.LINEAR)
        self.fbo = self.ctx.framebuffer(depth_attachment=self.atlas)

    def draw(self, lights, center: np.ndarray, radius: float) -> None:
        """Render every light's depth map into its tile of the atlas."""
        self._atlas(len(lights))
        self.fbo.use()
        self.fbo.clear(depth=1.0)
        self.ctx.enable_only(moderngl.DEPTH_TEST)
        matrices, texel = [], []
        for i, light in enumerate(lights):
            camera = light_camera(light, center, radius, self.size)
            near, far = camera.depth_range(center, radius)
            m = camera.projection_matrix(near, far) @ camera.view_matrix()
            matrices.append(m)
            if camera.fov_deg is None:
                texel.append(camera.height / self.size)
            else:
                distance = float(np.linalg.norm(center - camera.eye))
                texel.append(2 * distance * np.tan(np.deg2rad(camera.fov_deg) / 2) / self.size)
            self.fbo.viewport = (i * self.size, 0, self.size, self.size)
            self.program["view_proj"].write(m.T.astype(np.float32).tobytes())
            if self.base_depth > 0:
                self.program["light_place"].value = (
                    (*light.position, 1.0) if isinstance(light, PointLight)
                    else (*light.unit_direction, 0.0)
                )  # fmt: skip
            self.vao.render(moderngl.TRIANGLES)
        self.view_proj = np.array(matrices, np.float32)
        self.texel_mm = np.array(texel, np.float32)

    def bind(self, program: moderngl.Program, units: TextureUnits) -> None:
        """Set the surface program's shadow uniforms; the atlas on its sampler
        ``shadow_maps``'s unit of ``units``."""
        n = len(self.view_proj)
        program["light_view_proj"].write(np.transpose(self.view_proj, (0, 2, 1)).tobytes())
        program["shadow_offset"].write(self.texel_mm.tobytes())
        program["shadow_tiles"].value = n
        program["shadow_size"].value = float(self.size)
        units.use("shadow_maps", self.atlas, program)

    def _release_atlas(self) -> None:
        if self.fbo is not None:
            self.fbo.release()
            self.atlas.release()
        self.atlas, self.fbo = None, None

    def release(self) -> None:
        self._release_atlas()
        self.vao.release()
        self.program.release()
