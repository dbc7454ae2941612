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
- ``pem``: per region count K, partial environment maps on photometric-stereo
  maps (bumpy normals, albedo, a Blinn–Phong lobe s = 40): the largest error of
  a vertex's texture — each region's partial maps × its visibility ray-cast from
  the vertex towards it, as the shadow maps approximate — against the sum over
  every pixel with ray-cast visibility (largest and median over the vertices),
  beside the same with every region read at its top level (point lights), and
  the frame time of ``PemRenderer`` as a
  ratio to a point-light frame of the same PS material.
- ``vertices``: ray casting and U against the vertex count, and the memory
  that stays per vertex (visibility bits, frames, U).
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import trimesh

from render.camera import Camera
from render.environment._transfer import environment_coefficients, texture_at_vertex
from render.environment.map import synthetic_environment
from render.environment.pca import illumination_basis
from render.environment.renderer import EnvironmentRenderer
from render.environment.visibility import visibility_maps
from render.lights import DirectionalLight
from render.meshes import cloth, sphere
from render.pem.median_cut import median_cut, render_median_cut
from render.pem.regions import PartialMaps, partial_maps, region_radiance
from render.pem.renderer import PemRenderer
from render.points.renderer import Renderer
from rig.geometry import carry_light_cosine, direction_vector, nearest_directions
from rig.material import CompressedBTF, Material, PsView
from studies.render_speed import random_material

__all__ = ["brute_force_texture", "run"]

_VIEW_DEG = (30.0, 40.0)
_LOBE = {"specular": 0.5, "shininess": 40.0}


def brute_force_texture(btf, mesh, vertex: int, frame, environment, view_deg) -> np.ndarray:
    """(N, N, 3) float64: vertex ``vertex``'s texture summed over every environment pixel.

    Σ over the pixels above the vertex's horizon (``frame``: rows tangent,
    bitangent, normal) of radiance × solid angle × ray-cast visibility × the
    BTF at that light direction (the 4 nearest measured lights, Shepard
    weights carrying the light's cosine, as ``processing.btf.interpolate``) and at
    ``view_deg``.
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
    weights = carry_light_cosine(lights, btf.light_vectors, local[seen])
    g = np.zeros((len(btf.light_dirs_deg), 3))
    np.add.at(g, lights.indices, weights[..., None] * irradiance[seen, None, :])
    view = nearest_directions(btf.view_vectors, direction_vector(*view_deg)[None], k=4)
    for i in np.flatnonzero(np.any(g != 0, axis=1)):
        texture += g[i] * btf.blend(view.indices[0], view.weights[0], [i], [1.0])
    return texture


def _ps_material(size: int) -> Material:
    """Photometric-stereo maps of random bumps (slopes ~ 0.4) and albedo, size² texels."""
    rng = np.random.default_rng(1)
    normals = np.dstack([-0.4 * rng.standard_normal((size, size, 2)), np.ones((size, size))])
    normals /= np.linalg.norm(normals, axis=-1, keepdims=True)
    ps = PsView(
        name="cam0", normals=normals.astype(np.float32),
        albedo=rng.uniform(0.1, 0.9, (size, size, 3)).astype(np.float32),
        valid=np.ones((size, size), bool), reason=np.zeros((size, size), np.uint8),
        height_mm=np.zeros((size, size), np.float32), view_deg=(0.0, 0.0),
    )  # fmt: skip
    return Material(Path("bench-ps"), 20.0, size, ps={ps.name: ps})


def _hidden(mesh, vertex: int, frame, directions) -> np.ndarray:
    """(M,) bool: ``directions`` (M, 3) above the vertex's horizon (``frame``'s last row)
    in which a ray from the vertex hits the mesh."""
    positions = np.asarray(mesh.positions, np.float64)
    scene = trimesh.Trimesh(positions, np.asarray(mesh.faces, np.int64), process=False)
    origin = positions[vertex] + 1e-4 * np.linalg.norm(np.ptp(positions, axis=0)) * frame[2]
    up = np.flatnonzero(directions @ frame[2] > 0)
    hidden = np.zeros(len(directions), bool)
    hidden[up] = scene.ray.intersects_any(np.repeat(origin[None], len(up), 0), directions[up])
    return hidden


def _ps_at_vertex(ps, mesh, vertex, frame, eye, maps: PartialMaps, hidden) -> np.ndarray:
    """(N·N, 3): the PS texture at ``vertex`` (``frame``: rows tangent, bitangent, normal)
    seen from ``eye``: Σ over the regions of ``maps`` not ``hidden`` (K,)."""
    view = np.asarray(eye, np.float64) - np.asarray(mesh.positions[vertex], np.float64)
    normals = ps.normals.reshape(-1, 3).astype(np.float64) @ frame
    albedo = ps.albedo.reshape(-1, 3).astype(np.float64)
    light = region_radiance(maps, normals, view, surface=frame[2], albedo=albedo, **_LOBE)
    return light[~hidden].sum(axis=0)


def _every_pixel(environment, mesh, vertex, frame) -> PartialMaps:
    """Every environment pixel above the vertex's horizon and seen from it, as one region's
    texels at both levels: shaded and summed, the brute-force reference."""
    vectors, solid = environment.pixel_directions()
    directions = vectors.reshape(-1, 3)
    light = (environment.radiance * solid[..., None]).reshape(-1, 3) * environment.exposure
    seen = (directions @ frame[2] > 0) & ~_hidden(mesh, vertex, frame, directions)
    every = np.array([[0, int(seen.sum())]])
    return PartialMaps(
        directions=np.zeros((1, 3)), light=np.zeros((1, 3)), angular_radius=np.zeros(1),
        diffuse=every, glossy=every, texel_directions=directions[seen],
        texel_light=light[seen].astype(np.float64), levels=(0, 0),
    )  # fmt: skip


def _pem_rows(env, mesh, camera, probe, frames, counts) -> list[dict]:
    material = _ps_material(32)
    ps = material.frontal_ps()
    references = {
        v: _ps_at_vertex(ps, mesh, v, frames[v], camera.eye, _every_pixel(env, mesh, v, frames[v]),
                         np.zeros(1, bool))
        for v in probe
    }  # fmt: skip
    with Renderer(material, mesh, shadows=False, **_LOBE) as point:
        light = [DirectionalLight((0.3, -0.5, 0.8))]
        point.render(camera, light)
        _, point_s = _timed(lambda: point.render(camera, light))
    rows = []
    for count in counts:
        errors = {}
        for mip in (True, False):
            maps = partial_maps(env, count, shininess=_LOBE["shininess"], mip=mip)
            errors[mip] = [
                np.abs(
                    _ps_at_vertex(ps, mesh, v, frames[v], camera.eye, maps,
                                  _hidden(mesh, v, frames[v], maps.directions)) - ref
                ).max()
                / np.abs(ref).max()
                for v, ref in references.items()
            ]  # fmt: skip
        with PemRenderer(material, mesh, **_LOBE) as renderer:
            renderer.render_environment(camera, env, count=count)
            _, frame_s = _timed(
                lambda r=renderer, k=count: r.render_environment(camera, env, count=k)
            )
        rows.append({
            "row": "pem", "count": count, "lights": len(maps.directions),
            "max_error": round(float(max(errors[True])), 4),
            "max_error_point_lights": round(float(max(errors[False])), 4),
            "median_error": round(float(np.median(errors[True])), 4),
            "median_error_point_lights": round(float(np.median(errors[False])), 4),
            "frame_s": round(frame_s, 3), "frame_over_point_light": round(frame_s / point_s, 2),
        })  # fmt: skip
    return rows


def _timed(call):
    start = time.perf_counter()
    value = call()
    return value, time.perf_counter() - start


def run(quick: bool = False) -> list[dict]:
    """Rows ``row`` = visibility | pca | median_cut | pem | vertices (see the module)."""
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
    rows += _pem_rows(env, mesh, camera, probe, frames0, (4, 16) if quick else (1, 4, 16, 64))
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
