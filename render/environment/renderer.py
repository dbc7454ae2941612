"""A compressed BTF on a mesh under an HDR environment (seed 000 §5, seed 003).

``EnvironmentRenderer(material, mesh)`` casts every vertex's visibility map
once (:mod:`render.environment.visibility`); each environment (or rotation of it) becomes
the per-vertex coefficients U (:mod:`render.environment._transfer`, ``method=
"visibility"``) or, with ``method="pca"``, U from the PCA of A sampled
rotations (:mod:`render.environment.pca`), so turning the environment is interactive.
The fragment shader blends U across each triangle, blends the view slots by
the rule of ``rig.geometry`` and reconstructs the texture with the exposure f:
a per-view PCA from its c + 1 coefficients per slot, a global SVD from the
radiance g of every measured light direction (U = g) times the eigenmaps of
that light, weighted by the blended view weights. The BTF textures are the
point-light renderer's (``render.core.textures``).
"""

from __future__ import annotations

import moderngl
import numpy as np

from render._errors import RenderError
from render.camera import Camera
from render.core.gl import gl_context, image_framebuffer
from render.core.lookup import BLEND_METHODS
from render.core.programs import build_program
from render.core.textures import upload_btf
from render.core.units import TextureUnits
from render.environment._transfer import check_btf, environment_coefficients
from render.environment.map import EnvironmentMap
from render.environment.pca import check_basis_size, illumination_basis
from render.environment.visibility import DEFAULT_RESOLUTION, visibility_maps
from rig.geometry import spherical_triangulation
from rig.material import GlobalSVD

__all__ = ["ENV_METHODS", "EnvironmentRenderer"]

ENV_METHODS = ("visibility", "pca")
_COEF_WIDTH = 4096


def _view_table(vectors: np.ndarray, slots: np.ndarray, method: str) -> tuple[np.ndarray, int]:
    """Rows the shader scans: (x, y, z, slot) per valid slot, or 4 rows per triangle."""
    if method != "barycentric":
        return np.hstack([vectors, slots[:, None]]).astype(np.float32), len(vectors)
    try:
        mesh = spherical_triangulation(vectors)
    except ValueError as err:
        raise RenderError(f"view_method = 'barycentric': {err}; use 'nearest4'") from err
    rows = np.zeros((len(mesh.owner), 4, 4), np.float32)
    rows[:, :3, :3] = mesh.inverse
    rows[:, 3, :3] = slots[mesh.owner]
    return rows.reshape(-1, 4), len(mesh.owner)


def _corner_buffer(mesh) -> np.ndarray:
    """Per triangle corner: position, normal, uv, tangent, corner weights (floats) and
    the triangle's vertex ids (int32, stored bit for bit in the same rows)."""
    faces = np.asarray(mesh.faces, np.int64)
    corners = faces.reshape(-1)
    attributes = np.hstack([
        np.asarray(mesh.positions, np.float32), np.asarray(mesh.normals, np.float32),
        np.asarray(mesh.uvs, np.float32), np.asarray(mesh.tangents, np.float32),
    ])[corners]  # fmt: skip
    corner = np.tile(np.eye(3, dtype=np.float32), (len(faces), 1))
    ids = np.repeat(faces.astype(np.int32), 3, axis=0).view(np.float32)
    return np.ascontiguousarray(np.hstack([attributes, corner, ids]))


class EnvironmentRenderer:
    """Draws ``material``'s BTF on ``mesh`` lit by an environment map.

    Parameters
    ----------
    material : rig.material.Material
        Must hold a per-view PCA or a global-SVD BTF.
    mesh : render.meshes.Mesh
    tile_mm : float, optional
        As for :class:`render.Renderer` (the sample's side by default).
    method : {"visibility", "pca"}
        A new U per environment or rotation, or the PCA of illumination.
    resolution : int
        Hemicube n of the visibility maps (3n² rays per vertex; 8 for a faster preview).
    light_method, view_method : {"nearest4", "barycentric", "nearest"}
    rotations, components : int
        A and e of the PCA of illumination.
    """

    def __init__(
        self, material, mesh, *, tile_mm: float | None = None, method: str = "visibility",
        resolution: int = DEFAULT_RESOLUTION, light_method: str = "nearest4",
        view_method: str = "nearest4", rotations: int = 30, components: int = 5,
    ) -> None:  # fmt: skip
        self.btf = check_btf(material.btf)
        svd = isinstance(self.btf, GlobalSVD)
        if method not in ENV_METHODS:
            raise RenderError(f"method = {method!r}: valid are {ENV_METHODS}")
        if method == "pca":
            check_basis_size(rotations, components)
        if view_method not in BLEND_METHODS:
            raise RenderError(f"view_method = {view_method!r}: valid are {BLEND_METHODS}")
        tile = material.sample_mm if tile_mm is None else tile_mm
        if not (np.isfinite(tile) and tile > 0):
            raise RenderError(f"tile_mm = {tile_mm}: must be a positive number of mm")
        self.method, self.rotations, self.components = method, rotations, components
        self.mesh = mesh
        self.maps = visibility_maps(
            mesh, self.btf.light_vectors, resolution=resolution, light_method=light_method
        )
        valid = material.btf_slot_valid
        valid = np.ones(len(self.btf.view_dirs_deg), bool) if valid is None else np.asarray(valid)
        if not valid.any():
            raise RenderError("btf_slot_valid: no valid view slot to render")
        positions = np.asarray(mesh.positions, np.float64)
        lo, hi = positions.min(axis=0), positions.max(axis=0)
        self.bounds_center = (lo + hi) / 2
        self.bounds_radius = max(float(np.linalg.norm(hi - lo)) / 2, 1e-6)
        self.ctx = gl_context()
        self._owned: list = []
        self.textures = upload_btf(self.ctx, self.btf)
        table, rows = _view_table(
            self.btf.view_vectors[valid], np.flatnonzero(valid).astype(np.float32), view_method
        )
        view_table = self.ctx.texture((1, len(table)), 4, table, dtype="f4")
        view_table.filter = (moderngl.NEAREST, moderngl.NEAREST)
        self.vbo = self.ctx.buffer(_corner_buffer(mesh))
        self._owned += [view_table, self.vbo]
        self.program = build_program(self.ctx, "env_surface.vert", "env_surface.frag", defines={
            "COEF_WIDTH": _COEF_WIDTH, "CHANNELS": self.textures.channels,
            "PACKED": self.textures.packed,
            "SVD_COMPONENTS": self.textures.components if svd else 0,
        })  # fmt: skip
        self.vao = self.ctx.vertex_array(self.program, [(
            self.vbo, "3f 3f 2f 4f 3f 3i",
            "in_position", "in_normal", "in_uv", "in_tangent", "in_corner", "in_ids",
        )])  # fmt: skip
        self.units = TextureUnits(self.ctx)
        for name, texture in (("btf_images", self.textures.images), ("view_table", view_table),
                              ("btf_weights", self.textures.weights)):  # fmt: skip
            self.units.hold(name, texture)
        self.units.point(self.program)
        # U's rows per vertex: per view slot c + 1 coefficients; a global SVD's one g per light.
        rows_per_vertex = len(self.btf.light_dirs_deg) if svd else len(self.btf.view_dirs_deg)
        uniforms = {
            "n_slots": rows_per_vertex,
            "components": 0 if svd else self.btf.components, "view_rows": rows,
            "view_method": int(view_method == "barycentric"),
            "view_k": 1 if view_method == "nearest" else min(4, int(valid.sum())),
            "uv_scale": 1.0 / float(tile),
        }  # fmt: skip
        for name, value in uniforms.items():
            if name in self.program:
                self.program[name].value = value
        self._coef_texture: moderngl.Texture | None = None
        self._applied: tuple | None = None
        self._basis = None
        self._fbo: dict[tuple[int, int], moderngl.Framebuffer] = {}

    def coefficients(self, environment: EnvironmentMap) -> np.ndarray:
        """U for ``environment`` by this renderer's method (exposure not applied)."""
        if self.method == "visibility":
            return environment_coefficients(self.maps, environment, self.btf)
        source = environment.radiance
        if self._basis is None or self._basis[0] is not source:
            basis = illumination_basis(
                self.maps, environment.with_view(rotation_deg=0.0), self.btf,
                rotations=self.rotations, components=self.components,
            )  # fmt: skip
            self._basis = (source, basis)
        return self._basis[1].coefficients(environment.rotation_deg)

    def _apply(self, environment: EnvironmentMap) -> None:
        """Upload U unless this map at this rotation is what the texture holds already."""
        applied = self._applied
        if (
            applied is not None
            and applied[0] is environment.radiance
            and (applied[1] == environment.rotation_deg)
        ):
            return
        flat = self.coefficients(environment).reshape(-1, 3)
        rows = -(-len(flat) // _COEF_WIDTH)
        if rows > int(self.ctx.info["GL_MAX_TEXTURE_SIZE"]):
            raise RenderError(
                f"environment coefficients: {len(flat)} RGB texels exceed this GL's textures; "
                "use a mesh with fewer vertices or a material with fewer view slots/components"
            )
        padded = np.zeros((rows * _COEF_WIDTH, 3), np.float32)
        padded[: len(flat)] = flat
        if self._coef_texture is None or self._coef_texture.size != (_COEF_WIDTH, rows):
            if self._coef_texture is not None:
                self._coef_texture.release()
            self._coef_texture = self.ctx.texture((_COEF_WIDTH, rows), 3, dtype="f4")
            self._coef_texture.filter = (moderngl.NEAREST, moderngl.NEAREST)
        self._coef_texture.write(padded)
        self._applied = (environment.radiance, environment.rotation_deg)

    def render(self, camera: Camera, environment: EnvironmentMap) -> np.ndarray:
        """(H, W, 3) float32 linear image: radiance in the material's units times the
        environment's, times its exposure; 0 where no surface is seen."""
        if not isinstance(environment, EnvironmentMap):
            raise RenderError(
                f"environment: expected an EnvironmentMap, got {type(environment).__name__}"
            )
        self._apply(environment)
        program = self.program
        near, far = camera.depth_range(self.bounds_center, self.bounds_radius)
        view_proj = camera.projection_matrix(near, far) @ camera.view_matrix()
        program["view_proj"].write(view_proj.T.astype(np.float32).tobytes())
        for name, value in (("orthographic", camera.fov_deg is None), ("eye", tuple(camera.eye)),
                            ("toward_camera", tuple(-camera.forward)),
                            ("exposure", float(environment.exposure))):  # fmt: skip
            if name in program:
                program[name].value = value
        self.units.bind_held()
        self.units.use("env_coef", self._coef_texture, program)
        if camera.size not in self._fbo:
            self._fbo[camera.size] = image_framebuffer(self.ctx, camera.size)
        fbo = self._fbo[camera.size]
        fbo.use()
        fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
        self.ctx.enable_only(moderngl.DEPTH_TEST)
        self.vao.render(moderngl.TRIANGLES)
        pixels = np.frombuffer(fbo.read(components=4, dtype="f4"), np.float32)
        image = pixels.reshape(camera.size[1], camera.size[0], 4)[::-1, :, :3]
        return np.ascontiguousarray(image)

    def release(self) -> None:
        """Free the GPU objects (the shared context stays)."""
        for fbo in self._fbo.values():
            for attachment in (*fbo.color_attachments, fbo.depth_attachment):
                attachment.release()
            fbo.release()
        self._fbo.clear()
        for obj in (self.vao, self.program, self._coef_texture, *self._owned):
            if obj is not None:
                obj.release()
        self._owned.clear()
        self._coef_texture = None
        self.textures.release()

    def __enter__(self) -> EnvironmentRenderer:
        return self

    def __exit__(self, *exc) -> None:
        self.release()
