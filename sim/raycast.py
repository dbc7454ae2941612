"""Ray casting the scene mesh with trimesh (Embree through embreex when present).

This is the independent path: it never touches the GL rasteriser. It finds the
first triangle along each ray; :class:`sim.shading.SurfaceHits` then places the
exact hit on it.
"""

from __future__ import annotations

import numpy as np
import trimesh

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

    def sees(self, origins: np.ndarray, point: np.ndarray) -> np.ndarray:
        """(n,) bool: nothing lies between each origin (n, 3) and ``point`` (3,), mm.

        :meth:`occluded` along the unit directions towards the point, which are
        computed only for the rays that are cast.
        """
        origins = np.asarray(origins, dtype=np.float64)
        towards = np.asarray(point, dtype=np.float64) - origins
        cast = self._may_meet(origins, towards[:, 2] >= 0)
        dirs = towards[cast]
        dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
        visible = np.ones(len(origins), dtype=bool)
        self.rays += len(cast)
        if len(cast):
            visible[cast] = ~self._intersector.intersects_any(origins[cast], dirs)
        return visible

    def _may_meet(self, origins: np.ndarray, rising: np.ndarray) -> np.ndarray:
        """Indices of the rays that may meet the mesh: a ray that starts above its
        top and does not descend (from the plate's top towards a lamp: most of a
        frame's shadow rays) cannot."""
        return np.flatnonzero((origins[:, 2] <= self._top_z) | ~rising)
