"""Texel-exact views: the sample's normtexture grid as the pixels of an image.

A quad of the sample's size in z = 0, seen by an orthographic camera on +z
whose N × N pixels each land on one texel centre (row 0 at +y, column 0 at
−x: the layout of ``processing.btf.interpolate`` and of the simulator's
``btf_truth``). The quad's shading frame is turned so the camera sees it
from a chosen direction in its tangent frame: every pixel then shows the
material at that view direction, lit by a light given in the same frame.
This is how rendered images are compared texel by texel with the CPU
reference and with the simulator's truth.
"""

from __future__ import annotations

import numpy as np

from render.camera import Camera
from render.meshes import Mesh
from rig.geometry import direction_vector

__all__ = ["texel_camera", "texel_quad"]


def _rotation_to_z(v: np.ndarray) -> np.ndarray:
    """The rotation F with F @ v = +z (Rodrigues about v × z)."""
    z = np.array([0.0, 0.0, 1.0])
    axis = np.cross(v, z)
    s, c = np.linalg.norm(axis), float(np.dot(v, z))
    if s < 1e-12:
        return np.eye(3)
    k = axis / s
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + s * kx + (1 - c) * kx @ kx


def texel_quad(sample_mm: float, view_deg) -> tuple[Mesh, np.ndarray]:
    """The sample-sized quad, its shading frame turned so that a camera on +z
    sees it from ``view_deg`` = (θ, φ) degrees in its tangent frame.

    Returns
    -------
    mesh : Mesh
        Two triangles in z = 0, UVs 0…``sample_mm`` (one repeat of the sample).
    frame : (3, 3) float64
        The local → world rotation F: a light at local direction ``l`` is at
        world direction ``F @ l``.
    """
    f = _rotation_to_z(direction_vector(*view_deg))
    s = sample_mm / 2
    positions = np.array([[-s, -s, 0], [s, -s, 0], [s, s, 0], [-s, s, 0]], np.float32)
    uvs = (positions[:, :2] + s).astype(np.float32)  # mm of surface, 0…sample_mm
    normal, tangent = f @ [0.0, 0.0, 1.0], f @ [1.0, 0.0, 0.0]
    mesh = Mesh(
        positions=positions, normals=np.tile(normal, (4, 1)).astype(np.float32), uvs=uvs,
        tangents=np.tile([*tangent, 1.0], (4, 1)).astype(np.float32),
        faces=np.array([[0, 1, 2], [0, 2, 3]], np.uint32), name="texel quad",
    )  # fmt: skip
    return mesh, f


def texel_camera(sample_mm: float, n: int) -> Camera:
    """The orthographic camera on +z whose n × n pixels are the quad's texels."""
    return Camera.orthographic((0, 0, 100), (0, 0, 0), up=(0, 1, 0), height=sample_mm, size=(n, n))
