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

        Rays that start above the mesh's top and do not descend (from the
        plate's top towards a lamp: most of a frame's shadow rays) cannot meet
        it and are not cast; ``rays`` counts those cast.
        """
        origins = np.asarray(origins, dtype=np.float64)
        dirs = np.asarray(dirs, dtype=np.float64)
        cast = np.flatnonzero((origins[:, 2] <= self._top_z) | (dirs[:, 2] < 0))
        occluded = np.zeros(len(dirs), dtype=bool)
        self.rays += len(cast)
        if len(cast):
            occluded[cast] = self._intersector.intersects_any(origins[cast], dirs[cast])
        return occluded
