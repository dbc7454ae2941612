"""Per-vertex normals and tangent frames of a triangle mesh with UVs.

Tangents follow Lengyel's per-triangle accumulation: each triangle's
∂P/∂u and ∂P/∂v, solved from its edges and UV differences, are summed onto its
vertices, then the tangent is Gram–Schmidt orthogonalised against the vertex
normal and the handedness recorded as the sign of the bitangent.

A triangle with no area in space or in UV says nothing about a direction; it is
left out of the sums and counted. A vertex left with no usable sum gets a frame
built from its normal alone, so every frame is finite and orthonormal.

References
----------
E. Lengyel, "Computing tangent space basis vectors for an arbitrary mesh",
Terathon Software, 2001.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["TangentFrames", "tangent_frames", "vertex_normals"]

# Below this, a length or an area (relative to the mesh's own scale) counts as zero.
_REL_EPS = 1e-9


@dataclass(frozen=True)
class TangentFrames:
    """Tangent frames of a mesh.

    Attributes
    ----------
    tangents : (V, 4) float32
        xyz a unit tangent (along +u) orthogonal to the normal; w = ±1, the
        handedness: bitangent (along +v) = w · cross(normal, tangent).
    fallback : (V,) bool
        Vertices whose tangent came from the normal alone (no triangle with
        usable UVs touches them, or the UV direction was parallel to the normal).
    degenerate_faces : (F,) bool
        Triangles with zero area in space or in UV, left out of the sums.
    """

    tangents: np.ndarray
    fallback: np.ndarray
    degenerate_faces: np.ndarray


def _unit_rows(vectors: np.ndarray, scale: float) -> tuple[np.ndarray, np.ndarray]:
    """Rows scaled to unit length, and a mask of rows too short to scale."""
    length = np.linalg.norm(vectors, axis=1)
    short = length <= _REL_EPS * scale
    unit = vectors / np.where(short, 1.0, length)[:, None]
    unit[short] = 0.0
    return unit, short


def _any_perpendicular(normals: np.ndarray) -> np.ndarray:
    """A unit vector perpendicular to each unit normal (cross with the least aligned axis)."""
    axis = np.zeros_like(normals)
    axis[np.arange(len(normals)), np.argmin(np.abs(normals), axis=1)] = 1.0
    perpendicular = np.cross(normals, axis)
    return perpendicular / np.linalg.norm(perpendicular, axis=1, keepdims=True)


def _weld_seams(
    positions: np.ndarray,
    normals: np.ndarray,
    summed_u: np.ndarray,
    summed_v: np.ndarray,
    length_scale: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Share the sums between copies of one vertex split by a UV seam.

    A seam (a sphere's date line) splits a vertex into copies that each see the
    triangles of one side only: a one-sided sum tilts the tangent by half a
    segment. Copies at the same position with the same normal whose ∂P/∂u and
    ∂P/∂v all point the same way (within 45°) get the sum of the group; a
    mirrored seam, whose copies disagree, keeps its own sums.
    """
    key = np.round(np.concatenate([positions / max(length_scale, 1e-30), normals], axis=1), 6)
    _, group, count = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    group = group.ravel()
    if count.max() == 1:
        return summed_u, summed_v
    welded = []
    agree = np.ones(len(positions), dtype=bool)
    for summed in (summed_u, summed_v):
        total = np.zeros((len(count), 3))
        np.add.at(total, group, summed)
        own, _ = _unit_rows(summed, 0.0)
        shared, _ = _unit_rows(total[group], 0.0)
        agree &= np.sum(own * shared, axis=1) > np.cos(np.pi / 4)
        welded.append(total[group])
    # A group welds only when every copy agrees.
    group_agrees = np.bincount(group, weights=~agree, minlength=len(count)) == 0
    weld = (group_agrees[group] & (count[group] > 1))[:, None]
    return np.where(weld, welded[0], summed_u), np.where(weld, welded[1], summed_v)


def vertex_normals(positions: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Area-weighted vertex normals.

    Parameters
    ----------
    positions : (V, 3) float
    faces : (F, 3) int, counter-clockwise seen from the front

    Returns
    -------
    normals : (V, 3) float64, unit
    fallback : (V,) bool
        Vertices that no triangle with area touches; their normal is +z.
    """
    positions = np.asarray(positions, dtype=np.float64)
    corners = positions[faces]
    # The cross product's length is twice the area: area weighting for free.
    face_normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    summed = np.zeros_like(positions)
    for k in range(3):
        np.add.at(summed, faces[:, k], face_normals)
    scale = float(np.ptp(positions, axis=0).max()) ** 2 if len(positions) else 1.0
    normals, fallback = _unit_rows(summed, max(scale, 1e-30))
    normals[fallback] = (0.0, 0.0, 1.0)
    return normals, fallback


def tangent_frames(
    positions: np.ndarray, normals: np.ndarray, uvs: np.ndarray, faces: np.ndarray
) -> TangentFrames:
    """Per-vertex tangent frames from the UVs (Lengyel's accumulation).

    Parameters
    ----------
    positions : (V, 3) float
    normals : (V, 3) float, unit
    uvs : (V, 2) float
    faces : (F, 3) int

    Returns
    -------
    TangentFrames
        Finite, orthonormal frames for every vertex; see its attributes for the
        vertices and faces that needed a fallback.
    """
    positions = np.asarray(positions, dtype=np.float64)
    normals = np.asarray(normals, dtype=np.float64)
    uvs = np.asarray(uvs, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64)

    p0, p1, p2 = (positions[faces[:, k]] for k in range(3))
    w0, w1, w2 = (uvs[faces[:, k]] for k in range(3))
    edge1, edge2 = p1 - p0, p2 - p0
    duv1, duv2 = w1 - w0, w2 - w0
    uv_det = duv1[:, 0] * duv2[:, 1] - duv2[:, 0] * duv1[:, 1]

    length_scale = float(np.ptp(positions, axis=0).max()) if len(positions) else 1.0
    uv_scale = float(np.ptp(uvs, axis=0).max()) if len(uvs) else 1.0
    area2 = np.linalg.norm(np.cross(edge1, edge2), axis=1)
    degenerate = (area2 <= _REL_EPS * max(length_scale, 1e-30) ** 2) | (
        np.abs(uv_det) <= _REL_EPS * max(uv_scale, 1e-30) ** 2
    )

    # ∂P/∂u and ∂P/∂v times |det|: the sign of det kept, its size dropped, so a
    # triangle's weight grows with its size in space and a tiny UV area cannot blow up.
    sign = np.where(degenerate, 0.0, np.sign(uv_det))[:, None]
    dp_du = (duv2[:, 1:2] * edge1 - duv1[:, 1:2] * edge2) * sign
    dp_dv = (duv1[:, 0:1] * edge2 - duv2[:, 0:1] * edge1) * sign

    summed_u = np.zeros_like(positions)
    summed_v = np.zeros_like(positions)
    for k in range(3):
        np.add.at(summed_u, faces[:, k], dp_du)
        np.add.at(summed_v, faces[:, k], dp_dv)

    summed_u, summed_v = _weld_seams(positions, normals, summed_u, summed_v, length_scale)
    in_plane = summed_u - normals * np.sum(normals * summed_u, axis=1, keepdims=True)
    tangent, fallback = _unit_rows(in_plane, max(length_scale * uv_scale, 1e-30))
    if fallback.any():
        tangent[fallback] = _any_perpendicular(normals[fallback])

    handedness = np.where(np.sum(np.cross(normals, tangent) * summed_v, axis=1) < 0.0, -1.0, 1.0)
    tangents = np.concatenate([tangent, handedness[:, None]], axis=1).astype(np.float32)
    return TangentFrames(tangents=tangents, fallback=fallback, degenerate_faces=degenerate)
