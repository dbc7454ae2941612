"""``rig bench environment``: what environment lighting's accuracy costs in time.

A per-view PCA BTF (27 view slots × H1's 81 lights) on the draped cloth under
the studio environment. Rows:

- ``visibility``: per hemicube resolution n, the largest error of the texture
  at sample vertices against a brute-force sum over every environment pixel
  (:func:`brute_force_texture`), beside the ray-casting time, the time of a new
  U (an environment change) and of one frame, as a ratio to a point-light frame
  of the same material, mesh and camera drawn in the same run.
- ``pca``: per number e of eigen-weight-sets (A = 30 rotations), the error of
  U at a rotation between two samples against U computed there (and at a
  sampled rotation, the truncation alone), the PCA's
  precompute time and the time of one rotation.
- ``median_cut``: per light count K, the error of the median-cut lights
  (each ray-cast from the vertex, as the shadow maps approximate) against the
  same brute force, and the frame time with shadow maps, K/8 passes.
- ``vertices``: ray casting and U against the vertex count, and the memory
  that stays per vertex (visibility bits, frames, U).
"""

from __future__ import annotations

import time

import numpy as np
import trimesh

from render._env_transfer import environment_coefficients, texture_at_vertex
from render.bench import _material as random_material
from render.camera import Camera
from render.env_pca import illumination_basis
from render.env_renderer import EnvironmentRenderer
from render.environment import synthetic_environment
from render.lights import DirectionalLight
from render.median_cut import median_cut, render_median_cut
from render.meshes import cloth, sphere
from render.renderer import Renderer
from render.visibility import visibility_maps
from rig.geometry import direction_vector, nearest_directions
from rig.material import CompressedBTF

__all__ = ["brute_force_texture", "run_bench"]

_VIEW_DEG = (30.0, 40.0)


def brute_force_texture(btf, mesh, vertex: int, frame, environment, view_deg) -> np.ndarray:
    """(N, N, 3) float64: vertex ``vertex``'s texture summed over every environment pixel.

    Σ over the pixels above the vertex's horizon (``frame``: rows tangent,
    bitangent, normal) of radiance × solid angle × ray-cast visibility × the
    BTF at that light direction (the 4 nearest measured lights, Shepard
    weights, as ``processing.btf.interpolate``) and at ``view_deg``.
    """
    directions, solid = environment.pixel_directions()
    weighted = np.broadcast_to(solid[..., None] * environment.radiance, environment.radiance.shape)
    return _directional_sum(
        btf, mesh, vertex, frame, directions.reshape(-1, 3), weighted.reshape(-1, 3), view_deg
    )


def _directional_sum(btf, mesh, vertex, frame, directions, irradiance, view_deg) -> np.ndarray:
    """Σ over scene ``directions`` (m, 3) seen from the vertex of ``irradiance`` (m, 3) ×
    the BTF there; see :func:`brute_force_texture`."""
    frame = np.asarray(frame, np.float64)
    irradiance = np.asarray(irradiance, np.float64)
    local = directions @ frame.T
    up = np.flatnonzero(local[:, 2] > 0)
    positions = np.asarray(mesh.positions, np.float64)
    scene = trimesh.Trimesh(positions, np.asarray(mesh.faces, np.int64), process=False)
    origin = positions[vertex] + 1e-4 * np.linalg.norm(np.ptp(positions, axis=0)) * frame[2]
    hit = scene.ray.intersects_any(np.repeat(origin[None], len(up), 0), directions[up])
    seen = up[~hit]
    texture = np.zeros((*btf.mean.shape[1:3], 3))
    if len(seen) == 0:
        return texture
    lights = nearest_directions(btf.light_vectors, local[seen], k=4)
    g = np.zeros((len(btf.light_dirs_deg), 3))
    np.add.at(g, lights.indices, lights.weights[..., None] * irradiance[seen, None, :])
    view = nearest_directions(btf.view_vectors, direction_vector(*view_deg)[None], k=4)
    for i in np.flatnonzero(np.any(g != 0, axis=1)):
        texture += g[i] * btf.blend(view.indices[0], view.weights[0], [i], [1.0])
    return texture


def _timed(call):
    start = time.perf_counter()
    value = call()
    return value, time.perf_counter() - start


def run_bench(*, quick: bool = False) -> list[dict]:
    """Rows ``row`` = visibility | pca | median_cut | vertices (see the module)."""
    material = random_material("pca", 6, 32)  # 27 view slots × H1's 81 lights, c = 6
    btf: CompressedBTF = material.btf
    env = synthetic_environment("studio", height=32)
    mesh = cloth(segments=16 if quick else 48)
    size = (200, 150) if quick else (800, 600)
    camera = Camera.perspective((0, -700, 450), (0, 0, 60), fov_deg=35, size=size)
    view = nearest_directions(btf.view_vectors, direction_vector(*_VIEW_DEG)[None], k=4)
    probe = np.linspace(0, len(mesh.positions) - 1, 4 if quick else 8).astype(int)
    frames0 = visibility_maps(mesh, btf.light_vectors, resolution=2).frames
    references = {v: brute_force_texture(btf, mesh, v, frames0[v], env, _VIEW_DEG) for v in probe}
    with Renderer(material, mesh, shadows=False) as point:
        light = [DirectionalLight((0.3, -0.5, 0.8))]
        point.render(camera, light)
        _, point_s = _timed(lambda: point.render(camera, light))
    rows = []
    for n in (2, 4, 8) if quick else (2, 4, 8, 16, 32):
        with EnvironmentRenderer(material, mesh, resolution=n) as renderer:
            u, u_s = _timed(lambda r=renderer: r.coefficients(env))
            renderer.render(camera, env)
            _, frame_s = _timed(lambda r=renderer: r.render(camera, env))
            error = max(
                np.abs(texture_at_vertex(btf, u[v], view.indices[0], view.weights[0]) - ref).max()
                / np.abs(ref).max()
                for v, ref in references.items()
            )
            rows.append({
                "row": "visibility", "vis_res": n, "rays_per_vertex": 3 * n * n,
                "max_error": round(float(error), 4),
                "visibility_s": round(renderer.maps.seconds, 3),
                "new_env_s": round(u_s, 3), "frame_s": round(frame_s, 3),
                "frame_over_point_light": round(frame_s / point_s, 2),
            })  # fmt: skip
    maps = visibility_maps(mesh, btf.light_vectors, resolution=8)
    between = 6.0  # halfway between two of the 30 sampled rotations (12° apart)
    exact = environment_coefficients(maps, env.with_view(rotation_deg=between), btf)
    sampled = environment_coefficients(maps, env.with_view(rotation_deg=12.0), btf)
    for e in (1, 3, 5, 10) if not quick else (1, 5):
        basis = illumination_basis(maps, env, btf, rotations=30, components=e)
        turned, turn_s = _timed(lambda b=basis: b.coefficients(between))
        rows.append({
            "row": "pca", "components": e, "rotations": 30,
            "max_error": round(float(np.abs(turned - exact).max() / np.abs(exact).max()), 4),
            "error_at_sample": round(
                float(np.abs(basis.coefficients(12.0) - sampled).max() / np.abs(sampled).max()), 4
            ),
            "energy": round(basis.energy, 5), "precompute_s": round(basis.seconds, 2),
            "rotation_s": round(turn_s, 4),
        })  # fmt: skip
    for count in (4, 16) if quick else (4, 16, 64):
        directions, irradiance = median_cut(env, count)
        error = max(
            np.abs(
                _directional_sum(btf, mesh, v, frames0[v], directions, irradiance, _VIEW_DEG) - ref
            ).max()
            / np.abs(ref).max()
            for v, ref in references.items()
        )
        with Renderer(material, mesh) as renderer:
            render_median_cut(renderer, camera, env, count=count)
            _, frame_s = _timed(
                lambda r=renderer, k=count: render_median_cut(r, camera, env, count=k)
            )
        rows.append({
            "row": "median_cut", "count": count, "lights": len(directions),
            "max_error": round(float(error), 4), "frame_s": round(frame_s, 3),
            "frame_over_point_light": round(frame_s / point_s, 2),
        })  # fmt: skip
    big = (cloth(segments=24), mesh) if quick else (cloth(segments=24), mesh, sphere(segments=316))
    for shape in big:
        maps = visibility_maps(shape, btf.light_vectors, resolution=4)
        u, u_s = _timed(lambda m=maps: environment_coefficients(m, env, btf))
        rows.append({
            "row": "vertices", "mesh": shape.name, "vertices": len(shape.positions),
            "vis_res": 4, "visibility_s": round(maps.seconds, 2), "new_env_s": round(u_s, 2),
            "maps_MB": round(maps.nbytes / 2**20, 1), "U_MB": round(u.nbytes / 2**20, 1),
        })  # fmt: skip
        del u
    return rows
