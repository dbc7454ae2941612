"""``rig bench render``: frames per second at 800 × 600, against the number of
components c and of blended view slots, as a ratio to a plain textured quad.

A textured plane fills the frame under one point light (seed 000's setting);
each per-view-PCA fragment blends 1 (nearest), 3 (barycentric) or 4 (nearest
four) view slots of c + 1 float16 RGB images each (⌈3(c + 1)/4⌉ filtered
fetches, four values to a texel), from the 4 nearest measured lights. The
floor is the same plane with one filtered texture fetch per fragment, drawn
in the same run, so the ratio compares like with like on whatever GL this is
(llvmpipe on a CPU, or a GPU). Seed 001 reports 27–75 frames per second on a
2005 GPU.

Rows of kind ``mdf`` time the MDF's silhouettes: a torus filling the frame
(closed, as depth peeling needs) with the BTF alone, then with the MDF and
1, 2, 3 peeling passes, each as a ratio to the BTF alone in the same run (seed
001 Table 2: 6–75 frames per second for 1–3 passes). Rows of kind ``mdf
shadows`` time a ball's shadow on the textured plane: macro shadows alone and
with the MDF (seed 001 §4.2: pushed shadow maps, the MDF looked up per
fragment, the ambient term in shadow), as ratios to the same frame without
shadows.
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path

import moderngl
import numpy as np

from render.camera import Camera
from render.core.gl import gl_context, vertex_array
from render.core.programs import shader_source
from render.lights import PointLight
from render.meshes import merged, plane, sphere, torus
from render.points.renderer import Renderer
from rig.geometry import Sampling
from rig.material import CompressedBTF, GlobalSVD, Material, Mdf

__all__ = ["random_material", "run"]

_SIZE = (800, 600)
_SLOTS = {"nearest": 1, "barycentric": 3, "nearest4": 4}


def random_material(kind: str, components: int, size: int) -> Material:
    """A BTF of random float16 texels over 27 view slots × H1's 81 lights."""
    rng = np.random.default_rng(0)
    views, lights = Sampling.named("H2").directions[::3], Sampling.named("H1").directions
    n_views, n_lights = len(views), len(lights)
    if kind == "pca":
        btf = CompressedBTF(
            views, lights, rng.random((n_views, size, size, 3), np.float32).astype(np.float16),
            rng.uniform(-1, 1, (n_views, components, size, size, 3)).astype(np.float16),
            rng.normal(0, 0.1, (n_views, n_lights, components)).astype(np.float32),
            np.ones((n_views, n_lights), np.float32), np.full(n_views, components, np.int32),
        )  # fmt: skip
    else:
        btf = GlobalSVD(
            views, lights,
            rng.uniform(-1, 1, (components, n_lights, size, size, 3)).astype(np.float16),
            rng.normal(0, 0.1, (n_views, components)).astype(np.float32),
            np.ones(n_views, np.float32), components,
        )  # fmt: skip
    return Material(Path("bench"), 20.0, size, btf, np.ones(n_views, bool))


def _with_mdf(material: Material) -> Material:
    """``material`` with a random MDF (depths up to 1 mm) over its view slots."""
    rng = np.random.default_rng(1)
    views = material.btf.view_dirs_deg
    shape = (len(views), material.size, material.size)
    depth = rng.uniform(0.0, 1.0, shape) / np.cos(np.deg2rad(views[:, :1, None]))
    mdf = Mdf(depth.astype(np.float32), views, np.zeros(shape, np.uint8), np.ones(shape, np.uint8))
    return dataclasses.replace(material, mdf=mdf)


def _mdf_rows(size: tuple[int, int], texels: int, frames: int) -> list[dict]:
    """BTF + MDF on a torus at 1, 2, 3 peeling passes against the BTF alone on it."""
    material = _with_mdf(random_material("pca", 4, texels))
    mesh = torus(segments=96)
    camera = Camera.perspective((0, -210, 120), (0, 0, -8), fov_deg=38, size=size)
    lights = [PointLight((30.0, -120.0, 160.0), intensity=1e4)]
    cases = [
        ({"kind": "mdf", "mdf": mdf, "peel": peel},
         {"shadows": False, "mdf": mdf, "peel": max(peel, 1), "tile_mm": 10.0})
        for mdf, peel in ((False, 0), (True, 1), (True, 2), (True, 3))
    ]  # fmt: skip
    return _rows_against_first(material, mesh, camera, lights, cases, size, frames)


def _rows_against_first(material, mesh, camera, lights, cases, size, frames) -> list[dict]:
    """One row per ``(row fields, Renderer options)`` case: frames/s and CPU ms per frame,
    with their ratios to the first case's in the same run."""
    rows, btf_fps, btf_cpu_ms = [], None, None
    for fields, options in cases:
        with Renderer(material, mesh, **options) as renderer:
            fps, cpu_ms = _timing(lambda r=renderer: r.draw(camera, lights), frames)
            gl_renderer = renderer.ctx.info["GL_RENDERER"]
        btf_fps, btf_cpu_ms = btf_fps or fps, btf_cpu_ms or cpu_ms
        rows.append({
            **fields, "fps": round(fps, 3),
            "ratio_to_btf": round(fps / btf_fps, 4), "btf_fps": round(btf_fps, 2),
            "cpu_ms": round(cpu_ms, 1), "cpu_ratio_to_btf": round(btf_cpu_ms / cpu_ms, 4),
            "size": f"{size[0]}x{size[1]}", "gl_renderer": gl_renderer,
        })  # fmt: skip
    return rows


def _timing(draw, frames: int) -> tuple[float, float]:
    """Frames per second of the fastest of ``frames`` timed frames (after a warm-up one),
    and the least CPU time of the process in one frame, in ms: the best frame is the
    least disturbed by other work on a shared machine. On a software rasteriser the
    CPU time is the frame's whole cost (its threads are this process's) and hardly
    depends on other jobs; on a GPU it is only the driver's share."""
    ctx = gl_context()
    draw()  # compile, upload, warm the caches
    ctx.finish()
    best, best_cpu = np.inf, np.inf
    for _ in range(frames):
        start, start_cpu = time.perf_counter(), time.process_time()
        draw()
        ctx.finish()
        best = min(best, time.perf_counter() - start)
        best_cpu = min(best_cpu, time.process_time() - start_cpu)
    return 1.0 / best, 1000.0 * best_cpu


class _PlainQuad:
    """The speed floor: a renderer's mesh and first BTF texture layer, one fetch per fragment."""

    def __init__(self, renderer: Renderer, size: tuple[int, int]) -> None:
        ctx = self.ctx = renderer.ctx
        self.program = ctx.program(
            vertex_shader=shader_source("surface.vert"), fragment_shader=shader_source("plain.frag")
        )
        self.vao = vertex_array(ctx, self.program, renderer.vbo, renderer.ibo)
        self.program["uv_scale"].value = renderer.uv_scale
        self.program["btf_images"].value = 0
        self.texture = renderer.btf_textures.images
        self.bounds = renderer.bounds_center, renderer.bounds_radius
        self.colour = ctx.renderbuffer(size, 4, dtype="f4")
        self.depth = ctx.depth_renderbuffer(size)
        self.fbo = ctx.framebuffer([self.colour], self.depth)

    def draw(self, camera: Camera) -> None:
        near, far = camera.depth_range(*self.bounds)
        view_proj = camera.projection_matrix(near, far) @ camera.view_matrix()
        self.program["view_proj"].write(view_proj.T.astype(np.float32).tobytes())
        self.texture.use(location=0)
        self.fbo.use()
        self.fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
        self.ctx.enable_only(moderngl.DEPTH_TEST)
        self.vao.render(moderngl.TRIANGLES)

    def release(self) -> None:
        for obj in (self.fbo, self.colour, self.depth, self.vao, self.program):
            obj.release()


def run(quick: bool = False, *, size: tuple[int, int] = _SIZE) -> list[dict]:
    """Rows: ``kind``, ``components``, ``view_slots``, ``fps``, ``ratio_to_plain``
    (fps over the plain quad's), ``plain_fps``, ``cpu_ms`` (CPU time per frame, see
    ``_timing``), ``plain_cpu_ms``, ``size``, ``gl_renderer``; then the ``mdf`` rows:
    ``mdf``, ``peel`` (passes, 0 without the MDF), ``fps``, ``ratio_to_btf`` (fps over
    the BTF alone on the same torus), ``btf_fps``, ``cpu_ms``, ``cpu_ratio_to_btf`` (the
    BTF alone's CPU time per frame over this one's: the speed ratio that llvmpipe's
    shared-machine noise leaves alone), ``size``, ``gl_renderer``.

    ``quick``: c ∈ {4, 16}, 1 and 4 view slots, 64² textures, best of 2 frames
    (else c ∈ {1, 4, 8, 16}, 1/3/4 slots and the SVD, 128² textures, best of 5).
    ``size``: the frame's width and height in pixels.
    """
    components = (4, 16) if quick else (1, 4, 8, 16)
    methods = ("nearest", "nearest4") if quick else ("nearest", "barycentric", "nearest4")
    texels, frames = (64, 2) if quick else (128, 5)
    mesh = plane(size_mm=400.0, segments=4)
    camera = Camera.perspective((0, -90, 70), (0, 10, 0), fov_deg=60, size=size)
    lights = [PointLight((30.0, -20.0, 80.0), intensity=1e4)]
    runs = [("pca", c, m) for c in components for m in methods]
    if not quick:
        runs += [("svd", c, "nearest4") for c in components]
    with Renderer(random_material("pca", 1, texels), mesh, shadows=False) as floor:
        plain = _PlainQuad(floor, size)
        try:
            plain_fps, plain_cpu_ms = _timing(lambda: plain.draw(camera), frames)
        finally:
            plain.release()
    rows = []
    for kind, c, method in runs:
        with Renderer(random_material(kind, c, texels), mesh, view_method=method,
                      shadows=False) as renderer:  # fmt: skip
            fps, cpu_ms = _timing(lambda r=renderer: r.draw(camera, lights), frames)
            gl_renderer = renderer.ctx.info["GL_RENDERER"]
        rows.append({
            "kind": kind, "components": c,
            "view_slots": _SLOTS[method] if kind == "pca" else 4, "fps": round(fps, 3),
            "ratio_to_plain": round(fps / plain_fps, 4), "plain_fps": round(plain_fps, 2),
            "cpu_ms": round(cpu_ms, 1), "plain_cpu_ms": round(plain_cpu_ms, 1),
            "size": f"{size[0]}x{size[1]}", "gl_renderer": gl_renderer,
        })  # fmt: skip
    return rows + _mdf_rows(size, texels, frames) + _mdf_shadow_rows(size, texels, frames)


def _mdf_shadow_rows(size: tuple[int, int], texels: int, frames: int) -> list[dict]:
    """A ball's shadow on the plane: without shadows (the baseline), macro shadows, and
    shadows with the MDF; rows ``kind`` ("mdf shadows"), ``shadows``, ``mdf``, then as
    the ``mdf`` rows, the ratios to the frame without shadows."""
    material = _with_mdf(random_material("pca", 4, texels))
    ball = sphere(radius_mm=40.0, segments=32)
    ball = dataclasses.replace(ball, positions=ball.positions + np.float32([0.0, 10.0, 60.0]))
    mesh = merged([plane(size_mm=400.0, segments=4), ball], name="ball over plane")
    camera = Camera.perspective((0, -90, 70), (0, 10, 0), fov_deg=60, size=size)
    lights = [PointLight((30.0, -20.0, 80.0), intensity=1e4)]
    cases = [
        ({"kind": "mdf shadows", "shadows": shadows, "mdf": mdf}, {"shadows": shadows, "mdf": mdf})
        for shadows, mdf in ((False, False), (True, False), (True, True))
    ]
    return _rows_against_first(material, mesh, camera, lights, cases, size, frames)
