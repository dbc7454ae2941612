"""Ray casting the scene mesh with trimesh (Embree through embreex when present).

This is the independent path: it never touches the GL rasteriser. It finds the
first triangle along each ray; :class:`sim.shading.SurfaceHits` then places the
exact hit on it.
"""

from __future__ import annotations

import math

import numpy as np
import trimesh
from numba import njit

from sim.holder import SceneMesh

__all__ = ["RayCaster"]


class RayCaster:
    """First-hit and occlusion queries against a :class:`SceneMesh`."""

    def __init__(self, mesh: SceneMesh):
        tm = trimesh.Trimesh(mesh.vertices, mesh.faces, process=False, validate=False)
        if trimesh.ray.has_embree:
            from trimesh.ray.ray_pyembree import RayMeshIntersector
        else:  # pragma: no cover - embreex is a dependency of btfrig[sim]
            from trimesh.ray.ray_triangle import RayMeshIntersector
        self._intersector = RayMeshIntersector(tm)
        self._occlusion = _EmbreeOcclusion(tm) if trimesh.ray.has_embree else None
        self._top_z = float(mesh.vertices[:, 2].max())
        self.backend = "embree" if trimesh.ray.has_embree else "numpy"
        self.rays = 0  # rays cast, for the cost accounting

    def first_faces(self, origins: np.ndarray, dirs: np.ndarray) -> np.ndarray:
        """(n,) int64 index of the first triangle hit by each ray, −1 for none."""
        origins = np.broadcast_to(np.asarray(origins, np.float64), np.shape(dirs))
        self.rays += len(dirs)
        if len(dirs) == 0:
            return np.zeros(0, dtype=np.int64)
        return np.asarray(self._intersector.intersects_first(origins, dirs), dtype=np.int64)

    def occluded(self, origins: np.ndarray, dirs: np.ndarray) -> np.ndarray:
        """(n,) bool: something lies along each ray (the scene is below every lamp).

        Rays that cannot meet the mesh (:meth:`_may_meet`) are not cast;
        ``rays`` counts those cast.
        """
        origins = np.asarray(origins, dtype=np.float64)
        dirs = np.asarray(dirs, dtype=np.float64)
        cast = self._may_meet(origins, dirs[:, 2] >= 0)
        occluded = np.zeros(len(dirs), dtype=bool)
        self.rays += len(cast)
        if len(cast):
            occluded[cast] = self._intersector.intersects_any(origins[cast], dirs[cast])
        return occluded

    def sees(
        self, origins: np.ndarray, point: np.ndarray, where: np.ndarray | None = None
    ) -> np.ndarray:
        """(n,) bool: nothing lies between each origin (n, 3) and ``point`` (3,), mm;
        with ``where`` (n,) bool, asked of those origins only (the others read False).

        :meth:`occluded` along the unit directions towards the point, which are
        computed only for the rays that are cast.
        """
        origins = np.asarray(origins, dtype=np.float64)
        asked = np.ones(len(origins), dtype=bool) if where is None else np.asarray(where, bool)
        if self._occlusion is not None:
            point = np.asarray(point, dtype=np.float64)
            return self._occlusion.visible(origins, point, asked, self)
        towards = np.asarray(point, dtype=np.float64) - origins
        cast = np.intersect1d(self._may_meet(origins, towards[:, 2] >= 0), np.flatnonzero(asked))
        dirs = towards[cast]
        dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
        visible = asked.copy()
        self.rays += len(cast)
        if len(cast):
            visible[cast] = ~self._intersector.intersects_any(origins[cast], dirs)
        return visible

    def _may_meet(self, origins: np.ndarray, rising: np.ndarray) -> np.ndarray:
        """Indices of the rays that may meet the mesh: a ray that starts above its
        top and does not descend (from the plate's top towards a lamp: most of a
        frame's shadow rays) cannot."""
        return np.flatnonzero((origins[:, 2] <= self._top_z) | ~rising)


class _EmbreeOcclusion:
    """:meth:`RayCaster.sees` in one compiled pass and Embree's occlusion query: the
    rays trimesh's Embree intersector would cast (the same float32 origins, shifted
    and scaled as it shifts and scales the mesh, and unit directions), the same
    answers, without its float copies and its search for the nearest hit."""

    def __init__(self, tm: trimesh.Trimesh):
        self._tm = tm
        self._origin = tm.vertices.min(axis=0)
        self._scale = 100.0 / tm.scale  # trimesh's scale_to_box
        self._scene = None  # built for the first ray cast (a quarter second here)

    def _embree(self):
        if self._scene is None:
            from embreex import rtcore_scene
            from embreex.mesh_construction import TriangleMesh

            vertices = ((self._tm.vertices - self._origin) * self._scale).astype(np.float32)
            self._scene = rtcore_scene.EmbreeScene()
            TriangleMesh(scene=self._scene, vertices=vertices,
                         indices=self._tm.faces.astype(np.int32))  # fmt: skip
        return self._scene

    def visible(self, origins, point, asked, caster: RayCaster) -> np.ndarray:
        n = len(origins)
        rays_o, rays_d = np.empty((n, 3), np.float32), np.empty((n, 3), np.float32)
        index = np.empty(n, np.int64)
        m = _shadow_rays(np.ascontiguousarray(origins), point, asked, caster._top_z,
                         self._origin, self._scale, rays_o, rays_d, index)  # fmt: skip
        visible = asked.copy()
        caster.rays += m
        if m:
            hit = self._embree().run(rays_o[:m], rays_d[:m], query="OCCLUDED")
            visible[index[:m]] = hit == -1
        return visible


@njit(cache=True, nogil=True)
def _shadow_rays(origins, point, asked, top_z, shift, scale, rays_o, rays_d, index):
    """The ``asked`` rays towards ``point`` that may meet the mesh (:meth:`RayCaster._may_meet`),
    as trimesh hands them to Embree: the origin rounded to float32, shifted and scaled,
    rounded again; the unit direction rounded to float32 and normalised once more. Their
    count; ``index`` says whose they are."""
    m = 0
    for i in range(origins.shape[0]):
        x = point[0] - origins[i, 0]
        y = point[1] - origins[i, 1]
        z = point[2] - origins[i, 2]
        if not asked[i] or (origins[i, 2] > top_z and z >= 0):
            continue
        length = math.sqrt((x * x + y * y) + z * z)
        fx, fy, fz = np.float32(x / length), np.float32(y / length), np.float32(z / length)
        squares = (float(fx * fx) + float(fy * fy)) + float(fz * fz)
        inverse = 1.0 / math.sqrt(squares)
        rays_d[m, 0], rays_d[m, 1], rays_d[m, 2] = fx * inverse, fy * inverse, fz * inverse
        for k in range(3):
            rays_o[m, k] = (float(np.float32(origins[i, k])) - shift[k]) * scale
        index[m] = i
        m += 1
    return m
