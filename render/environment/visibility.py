"""Per-vertex visibility maps: which directions above each vertex see the environment.

Seed 000 §5.2 and seed 003: every vertex carries a hemicube over its tangent
frame — the top face (n × n texels) perpendicular to the normal, four half
faces (n × n/2) around it, their sides along the tangent and bitangent — and
per texel whether the environment is visible that way (a ray cast against the
mesh itself: macro self-shadowing). The hemicube is laid out in the tangent
frame, the sample frame of the measurement, so a texel's direction in that
frame is the same for every vertex: its four nearest measured light directions
and their weights (``rig.geometry``, as the point-light path blends lights)
are one table shared by all vertices, and only the visibility bits and the
vertex's frame are stored per vertex. Where in the environment map a texel
looks (the seed's stored position) follows from the frame when an
environment is applied (:mod:`render.environment._transfer`).

Rays are cast by trimesh on Embree, the mesh against itself; each starts a
small offset off the surface along the normal.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import trimesh

from render.core.hemisphere import hemicube, light_table

__all__ = ["DEFAULT_RESOLUTION", "VisibilityMaps", "visibility_maps"]

#: The hemicube's n by default: a 3° sun reaches every vertex facing it with 0.6–1.4 × its
#: light (0.3–2.1 × at n = 8, the faster preview), and a studio's sharp-edged softboxes are
#: within 3 % of the brute-force sum (docs/render.md, "What accuracy costs").
DEFAULT_RESOLUTION = 16
# Rays per ray-casting call: bounds the memory of the cast (about 100 bytes a ray).
_RAYS_PER_CAST = 1 << 20
# Ray origins leave the surface by this fraction of the mesh's bounding-box diagonal.
_OFFSET = 1e-4


@dataclass(frozen=True)
class VisibilityMaps:
    """Every vertex's hemicube: visibility bits, frame, and the shared light table.

    Attributes
    ----------
    resolution : int
        Hemicube n (T = 3n² texels).
    directions : (T, 3) float64
        Texel directions in the tangent frame (the sample frame).
    solid_angles : (T,) float64
        Steradians per texel.
    light_indices, light_weights : (T, k) int64, float64
        The measured light directions each texel blends and their weights, carrying
        the light's cosine (``render.core.hemisphere.light_table``).
    light_method : str
    frames : (V, 3, 3) float32
        Rows: each vertex's tangent, bitangent and normal in the scene; a
        texel's scene direction is ``directions @ frames[v]``.
    visible : (V, ⌈T/8⌉) uint8
        Visibility bits per texel (``np.unpackbits(..., count=T)``), 1 = the
        environment is seen that way.
    seconds : float
        Time spent casting rays.
    """

    resolution: int
    directions: np.ndarray
    solid_angles: np.ndarray
    light_indices: np.ndarray
    light_weights: np.ndarray
    light_method: str
    frames: np.ndarray
    visible: np.ndarray
    seconds: float

    @property
    def texels(self) -> int:
        return len(self.directions)

    def visibility(self, vertices=slice(None)) -> np.ndarray:
        """(V', T) bool visibility of the selected vertices."""
        return np.unpackbits(self.visible[vertices], axis=1, count=self.texels).astype(bool)

    @property
    def nbytes(self) -> int:
        return self.frames.nbytes + self.visible.nbytes


def _frames(mesh) -> np.ndarray:
    normals = np.asarray(mesh.normals, np.float64)
    tangents = np.asarray(mesh.tangents, np.float64)
    bitangents = tangents[:, 3:4] * np.cross(normals, tangents[:, :3])
    return np.stack([tangents[:, :3], bitangents, normals], axis=1)


def visibility_maps(
    mesh, light_vectors, *, resolution: int = DEFAULT_RESOLUTION, light_method: str = "nearest4"
) -> VisibilityMaps:
    """Cast every vertex's hemicube against the mesh.

    Parameters
    ----------
    mesh : render.meshes.Mesh
    light_vectors : (n, 3) array
        The material's measured light directions (sample frame).
    resolution : int
        Hemicube n (even); 3n² rays per vertex.
    light_method : {"nearest4", "barycentric", "nearest"}
        How a texel's direction blends the measured lights.

    Returns
    -------
    VisibilityMaps
    """
    directions, solid_angles = hemicube(resolution)
    light_indices, light_weights = light_table(light_vectors, directions, light_method)
    frames = _frames(mesh)
    positions = np.asarray(mesh.positions, np.float64)
    scene = trimesh.Trimesh(positions, np.asarray(mesh.faces, np.int64), process=False)
    offset = _OFFSET * float(np.linalg.norm(np.ptp(positions, axis=0)) or 1.0)
    texels = len(directions)
    visible = np.zeros((len(positions), (texels + 7) // 8), np.uint8)
    per_cast = max(1, _RAYS_PER_CAST // texels)
    started = time.perf_counter()
    for first in range(0, len(positions), per_cast):
        part = slice(first, first + per_cast)
        rays = directions @ frames[part]  # (v, T, 3)
        origins = positions[part] + offset * frames[part, 2]
        hit = scene.ray.intersects_any(
            np.repeat(origins, texels, axis=0), rays.reshape(-1, 3)
        ).reshape(-1, texels)
        visible[part] = np.packbits(~hit, axis=1)
    seconds = time.perf_counter() - started
    return VisibilityMaps(
        resolution=resolution, directions=directions, solid_angles=solid_angles,
        light_indices=light_indices, light_weights=light_weights, light_method=light_method,
        frames=frames.astype(np.float32), visible=visible, seconds=seconds,
    )  # fmt: skip
