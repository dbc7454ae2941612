"""The renderer: a measured material on a mesh under point and directional lights.

A renderer compiles its shader for what the material holds (a per-view PCA or
global-SVD BTF, photometric-stereo maps, or both) and for each number of
lights it is asked for; textures, lookups, programs and buffers are made once
and reused for every frame. Per fragment the view
and light directions go to the tangent frame, become (θ, φ), and blend the
measured view slots and lights exactly as ``processing.btf.interpolate``
(seed 000 §4.2 eq. (3)–(5), seed 001 §5), with macro shadows from per-light
shadow maps filtered to soft edges. See ``docs/render.md``.
"""

from __future__ import annotations

from typing import ClassVar

import moderngl
import numpy as np

from render._errors import RenderError
from render.camera import Camera
from render.core.gl import gl_context, image_framebuffer, mesh_buffers, vertex_array
from render.core.lookup import build_lookup
from render.core.programs import build_program
from render.core.textures import (
    BtfTextures,
    PbrTextures,
    PsTextures,
    light_cosine_texture,
    lookup_texture,
    upload_btf,
    upload_pbr,
    upload_ps,
)
from render.core.units import TextureUnits
from render.lights import MAX_LIGHTS, DirectionalLight, PointLight
from render.points._mdf_shading import MdfShading, mdf_shading
from render.points._options import check_shading, checked_layers, checked_tile_mm
from render.points._shadows import ShadowMaps
from render.points.peel import mdf_silhouettes
from rig.material import CompressedBTF, Material

__all__ = ["MAX_LIGHTS", "Renderer"]


class Renderer:
    """Draws ``material`` on ``mesh``; :meth:`render` gives a linear float image.

    Parameters
    ----------
    material : rig.material.Material
        Its BTF (``pca`` or ``svd``) and/or its frontal photometric-stereo view.
    mesh : render.meshes.Mesh
        Positions in scene units, UVs in mm of surface.
    tile_mm : float, optional
        mm of surface one repeat of the sample covers (texture coordinate =
        uv / tile_mm); the sample's own side ``material.sample_mm`` by default
        (true scale).
    layers : tuple of {"btf", "ps", "pbr"}, optional
        What shades the surface; by default the BTF and PS maps the material
        holds (its PBR fit when it holds nothing else).
        ``"ps"`` alone: Lambert on the bump-mapped normals, times the albedo,
        plus the specular lobe. With ``"btf"``: the BTF (whose normtextures
        already hold the diffuse shading of the mesostructure) plus only the
        specular lobe of the bump-mapped normals. ``"pbr"`` (alone): the
        material's glTF PBR fit (``render/shaders/pbr.glsl``), without the MDF.
    light_method, view_method : {"nearest4", "barycentric", "nearest"}
        How measured lights and view slots are blended (``processing.btf.interpolate``).
    specular, shininess : float
        Blinn–Phong lobe of the PS layer (weight ≥ 0, exponent > 0); 0 = none.
    shadows : bool
        Macro shadows of the mesh (shadow maps, 5×5 PCF).
    shadow_size : int
        Texels per side of each light's shadow map.
    mdf : bool or None
        Use the material's MDF (seed 001 §4); None: when the material holds
        one. Mesostructure silhouettes by depth peeling (``render.points.peel``), and
        mesostructure-aware shadows: tested where the view ray meets the
        mesostructure, p − s·D(x, y, v)·v (s = tile_mm / sample_mm), against
        shadow maps holding the mesostructure's base, shadowed points shaded
        by the ambient term.
    peel : int
        Peeling passes with the MDF (1…8): intervals of a ray inside the mesh
        tested, nearest first.
    ambient : float
        With the MDF: the fraction a ∈ [0, 1] of each light's irradiance that
        reaches the points it shadows as uniform skylight (radiance a·E/π),
        shading them by the ambient term L_a, the BTF integrated over all light
        directions (``render.points.ambient``); 0: shadows are black.

    Notes
    -----
    View slots with ``material.btf_slot_valid`` false are skipped: the view
    blend is built over the valid slots only, so their weights sum to one and
    a direction at an empty slot takes its valid neighbours.
    """

    #: Shader features a subclass turns on (``render.pem.renderer``: PEM 1).
    _features: ClassVar[dict[str, int]] = {"PEM": 0}

    def __init__(
        self,
        material: Material,
        mesh,
        *,
        tile_mm: float | None = None,
        layers: tuple[str, ...] | None = None,
        light_method: str = "nearest4",
        view_method: str = "nearest4",
        specular: float = 0.0,
        shininess: float = 40.0,
        shadows: bool = True,
        shadow_size: int = 1024,
        mdf: bool | None = None,
        peel: int = 2,
        ambient: float = 0.2,
    ) -> None:
        self.layers = checked_layers(material, layers)
        tile = checked_tile_mm(material, tile_mm)
        check_shading(light_method=light_method, view_method=view_method, specular=specular,
                      shininess=shininess, ambient=ambient)  # fmt: skip
        # the MDF's ambient term integrates the BTF: the PBR fit draws without it
        with_mdf = material.mdf is not None and "pbr" not in self.layers if mdf is None else mdf
        btf = material.btf if "btf" in self.layers else None
        self.ctx = gl_context()
        self.units = TextureUnits(self.ctx)
        self.uv_scale = 1.0 / tile
        self._static: dict[str, object] = {"uv_scale": self.uv_scale}
        self._defines = self._base_defines(btf, shadows=shadows, mdf=bool(with_mdf))
        self._programs: dict[int, tuple[moderngl.Program, moderngl.VertexArray]] = {}
        self._framebuffers: dict[tuple[int, int], moderngl.Framebuffer] = {}
        self._owned: list = []
        self._upload_mesh(mesh)
        self.btf_textures = (
            None if btf is None
            else self._upload_btf(btf, material.btf_slot_valid, light_method, view_method)
        )  # fmt: skip
        self.ps_textures = (
            self._upload_ps(material.frontal_ps(), specular, shininess)
            if "ps" in self.layers else None
        )  # fmt: skip
        self.pbr_textures = self._upload_pbr(material.pbr) if "pbr" in self.layers else None
        self.mdf = (
            self._upload_mdf(material, btf, light_method, view_method, ambient, tile)
            if with_mdf else None
        )  # fmt: skip
        self.shadows = self._shadow_maps(shadow_size) if shadows else None
        self.silhouettes = mdf_silhouettes(
            self.ctx, mesh, self.vbo, self.ibo, self.mdf and self.mdf.texture, peel=peel,
            texture_scale=tile / material.sample_mm, uv_scale=self.uv_scale,
            asked=mdf is not None,
        )  # fmt: skip
        self._program(1)  # a shader this GL cannot compile fails here, not at the first frame

    # ---- setup steps, in the order __init__ takes them ----

    def _base_defines(self, btf, *, shadows: bool, mdf: bool) -> dict[str, int]:
        """The surface shader's constants before the layers add theirs."""
        return {
            "BTF_KIND": 0 if btf is None else (1 if isinstance(btf, CompressedBTF) else 2),
            "PS": int("ps" in self.layers),
            "PBR": int("pbr" in self.layers),
            "MDF": int(mdf),
            "SHADOWS": int(bool(shadows)),
            "MDF_SHADOWS": int(mdf and shadows),
            "AMBIENT": 0,
            **self._features,
        }

    def _upload_mesh(self, mesh) -> None:
        """The mesh's buffers, its bounding sphere, and the depth pre-pass's program."""
        self.mesh = mesh
        positions = np.asarray(mesh.positions, np.float64)
        lo, hi = positions.min(axis=0), positions.max(axis=0)
        self.bounds_center = (lo + hi) / 2
        self.bounds_radius = max(float(np.linalg.norm(hi - lo)) / 2, 1e-6)
        self.vbo, self.ibo = mesh_buffers(self.ctx, mesh)
        self._depth_program = build_program(self.ctx, "depth.vert", "depth.frag")
        self._depth_vao = vertex_array(self.ctx, self._depth_program, self.vbo, self.ibo)
        self._owned += [self.vbo, self.ibo, self._depth_program, self._depth_vao]

    def _attach(self, textures: dict, uniforms: dict | None = None,
                defines: dict | None = None) -> None:  # fmt: skip
        """A layer's textures held on their samplers' units, and its uniforms and shader
        constants, for every surface program."""
        for name, texture in textures.items():
            self.units.hold(name, texture)
        self._static.update(uniforms or {})
        self._defines.update(defines or {})

    def _upload_btf(self, btf, slot_valid, light_method: str, view_method: str) -> BtfTextures:
        """The BTF's textures and the lookups of its valid view slots and its lights."""
        valid = np.ones(len(btf.view_dirs_deg), bool) if slot_valid is None else slot_valid
        valid = np.asarray(valid, bool)
        if valid.shape != (len(btf.view_dirs_deg),) or not valid.any():
            raise RenderError(
                f"btf_slot_valid has shape {valid.shape} with {int(valid.sum())} valid slots; "
                f"expected ({len(btf.view_dirs_deg)},) with at least one valid view slot"
            )
        textures = upload_btf(self.ctx, btf)
        for role, table, method, index in (
            ("view", btf.view_vectors[valid], view_method, np.flatnonzero(valid)),
            ("light", btf.light_vectors, light_method, None),
        ):
            lookup = build_lookup(table, method, index=index)
            cells = lookup_texture(self.ctx, lookup)
            self._owned.append(cells)
            # Constants of the shader: its loops have fixed lengths and no branch on the method.
            prefix = role.upper()
            self._attach({f"{role}_cells": cells}, defines={
                f"{prefix}_METHOD": lookup.code, f"{prefix}_K": lookup.k,
                f"{prefix}_CANDIDATES": lookup.length,
            })  # fmt: skip
        cosines = light_cosine_texture(self.ctx, btf.light_vectors)
        self._owned.append(cosines)
        self._attach(
            {"btf_weights": textures.weights, "btf_images": textures.images,
             "light_cosines": cosines},
            {"n_table_lights": textures.n_lights},
            {"COMPONENTS": textures.components, "CHANNELS": textures.channels,
             "PACKED": textures.packed},
        )  # fmt: skip
        return textures

    def _upload_ps(self, view, specular: float, shininess: float) -> PsTextures:
        """The photometric-stereo maps and the Blinn–Phong lobe of the PS layer."""
        textures = upload_ps(self.ctx, view)
        self._attach({"ps_albedo": textures.albedo, "ps_normals": textures.normals},
                     {"specular": float(specular), "shininess": float(shininess)})  # fmt: skip
        return textures

    def _upload_pbr(self, maps) -> PbrTextures:
        """The PBR fit's maps and its sheen table."""
        textures = upload_pbr(self.ctx, maps)
        self._attach({"pbr_maps": textures.maps, "sheen_lut": textures.sheen},
                     {"pbr_white": float(maps.attrs.get("white", 1.0))})  # fmt: skip
        return textures

    def _upload_mdf(self, material, btf, light_method: str, view_method: str, ambient: float,
                    tile_mm: float) -> MdfShading:  # fmt: skip
        """The MDF, its shadow uniforms and the ambient term (``render.points._mdf_shading``)."""
        shading = mdf_shading(self.ctx, material, btf, view_method=view_method,
                              light_method=light_method, ambient=ambient,
                              tile_mm=tile_mm)  # fmt: skip
        self._attach(shading.textures(), shading.uniforms, shading.defines())
        return shading

    def _shadow_maps(self, size: int) -> ShadowMaps:
        """The shadow-map atlas, at the mesostructure's base where the MDF is drawn."""
        base_depth = 0.0 if self.mdf is None else self.mdf.base_depth
        return ShadowMaps(self.ctx, self.vbo, self.ibo, size=size, base_depth=base_depth)

    # ---- drawing ----

    def _program(self, n_lights: int) -> tuple[moderngl.Program, moderngl.VertexArray]:
        """The surface program for ``n_lights`` ≥ 1 lights, compiled on first use.

        The number of lights is a constant of the shader, so its per-light
        arrays stay in registers (a software rasteriser runs twice as fast).
        """
        if n_lights not in self._programs:
            program = build_program(self.ctx, "surface.vert", "surface.frag",
                                    defines={**self._defines, "N_LIGHTS": n_lights})  # fmt: skip
            self.units.point(program)
            for name, value in self._static.items():
                if name in program:
                    program[name].value = value
            self._programs[n_lights] = (
                program,
                vertex_array(self.ctx, program, self.vbo, self.ibo),
            )
        return self._programs[n_lights]

    def _framebuffer(self, size: tuple[int, int]) -> moderngl.Framebuffer:
        if size not in self._framebuffers:
            self._framebuffers[size] = image_framebuffer(self.ctx, size)
        return self._framebuffers[size]

    def render(self, camera: Camera, lights) -> np.ndarray:
        """The linear image of the scene.

        Parameters
        ----------
        camera : Camera
        lights : sequence of PointLight / DirectionalLight
            At most :data:`MAX_LIGHTS`.

        Returns
        -------
        (H, W, 3) float32
            Radiance in the material's units (its ``btf_units`` times the
            lights' colour · intensity); 0 where no surface is seen.
        """
        fbo = self.draw(camera, lights)
        pixels = np.frombuffer(fbo.read(components=4, dtype="f4"), np.float32)
        image = pixels.reshape(camera.size[1], camera.size[0], 4)[::-1, :, :3]
        return np.ascontiguousarray(image)

    def draw(self, camera: Camera, lights) -> moderngl.Framebuffer:
        """Draw the scene into the renderer's float framebuffer of ``camera.size``, no read-back
        (an interactive view or a timing uses this; :meth:`render` reads the image)."""
        lights = list(lights)
        if len(lights) > MAX_LIGHTS or not all(
            isinstance(light, PointLight | DirectionalLight) for light in lights
        ):
            raise RenderError(
                f"lights: expected up to {MAX_LIGHTS} PointLight/DirectionalLight, got "
                f"{[type(light).__name__ for light in lights]}"
            )
        if lights:
            self._draw_lit(camera, lights)
        else:
            fbo = self._framebuffer(camera.size)
            fbo.use()
            fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
        return self._framebuffer(camera.size)

    def _draw_lit(self, camera: Camera, lights: list) -> None:
        program, vao = self._program(len(lights))
        place = np.zeros((len(lights), 4), np.float32)
        emission = np.zeros((len(lights), 3), np.float32)
        for i, light in enumerate(lights):
            if isinstance(light, PointLight):
                place[i] = (*light.position, 1.0)
            else:
                place[i] = (*light.unit_direction, 0.0)
            emission[i] = light.emission
        program["light_place"].write(place.tobytes())
        program["light_emission"].write(emission.tobytes())
        if self.shadows is not None:
            self.shadows.draw(lights, self.bounds_center, self.bounds_radius)
            self.shadows.bind(program, self.units)
        self._bind_lights(program, lights, self.units)
        near, far = camera.depth_range(self.bounds_center, self.bounds_radius)
        view_proj = camera.projection_matrix(near, far) @ camera.view_matrix()
        view_proj = view_proj.T.astype(np.float32).tobytes()
        program["view_proj"].write(view_proj)
        for name, value in (("orthographic", camera.fov_deg is None), ("eye", tuple(camera.eye)),
                            ("toward_camera", tuple(-camera.forward))):  # fmt: skip
            if name in program:
                program[name].value = value
        fbo = self._depth_pass(camera, view_proj)
        self.units.bind_held()
        fbo.use()
        # Shade only what the depth pass left in front (depth equal): where the mesh
        # folds over itself each pixel runs the costly shader once, not per layer.
        self.ctx.depth_func = "<=" if self.silhouettes is None else "=="
        vao.render(moderngl.TRIANGLES)
        self.ctx.depth_func = "<"

    def _depth_pass(self, camera: Camera, view_proj: bytes) -> moderngl.Framebuffer:
        """The framebuffer cleared, its depth that of the surfaces to shade: the nearest
        (depth pre-pass) or, with the MDF, those whose rays meet the mesostructure."""
        fbo = self._framebuffer(camera.size)
        fbo.use()
        fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
        if self.silhouettes is not None:
            self.silhouettes.draw(camera, view_proj, fbo.depth_attachment, self.units)
            return fbo
        self.ctx.enable_only(moderngl.DEPTH_TEST)
        self._depth_program["view_proj"].write(view_proj)
        fbo.color_mask = False, False, False, False
        self._depth_vao.render(moderngl.TRIANGLES)
        fbo.color_mask = True, True, True, True
        return fbo

    def coverage(self, camera: Camera) -> np.ndarray:
        """(H, W) bool: the pixels where the surface is drawn (with the MDF, where a
        ray meets the mesostructure), row 0 at the top like :meth:`render`."""
        near, far = camera.depth_range(self.bounds_center, self.bounds_radius)
        view_proj = camera.projection_matrix(near, far) @ camera.view_matrix()
        fbo = self._depth_pass(camera, view_proj.T.astype(np.float32).tobytes())
        depth = np.frombuffer(fbo.read(components=1, attachment=-1, dtype="f4"), np.float32)
        return np.ascontiguousarray(depth.reshape(camera.size[1], camera.size[0])[::-1] < 1.0)

    def _bind_lights(self, program: moderngl.Program, lights: list, units: TextureUnits) -> None:
        """A subclass's per-frame uniforms of its ``lights`` and its textures (on ``units``)."""

    def release(self) -> None:
        """Free the GPU objects (the shared context stays)."""
        for fbo in self._framebuffers.values():
            for attachment in (*fbo.color_attachments, fbo.depth_attachment):
                attachment.release()
            fbo.release()
        self._framebuffers.clear()
        for part in (self.shadows, self.btf_textures, self.ps_textures, self.pbr_textures,
                     self.silhouettes, self.mdf):  # fmt: skip
            if part is not None:
                part.release()
        self.shadows = self.btf_textures = self.ps_textures = self.pbr_textures = None
        self.silhouettes = self.mdf = None
        for program, vao in self._programs.values():
            vao.release()
            program.release()
        self._programs.clear()
        for obj in reversed(self._owned):
            obj.release()
        self._owned.clear()

    def __enter__(self) -> Renderer:
        return self

    def __exit__(self, *exc) -> None:
        self.release()
