"""Lookup tables that let a fragment shader blend measured directions exactly like
:mod:`rig.geometry` (and so like ``processing.btf.interpolate``).

The hemisphere is mapped to an R × R grid (hemi-octahedral: a direction d with
d_z ≥ 0 goes to p = (d_x, d_y) / (|d_x| + |d_y| + d_z), rotated by 45° onto
[−1, 1]²). For every grid cell the CPU lists the *candidates*: every table
direction (nearest-k Shepard) or spherical triangle (barycentric) that can be
chosen for some direction inside the cell, in ascending index order. The
shader then picks among a cell's candidates with the same rule as the CPU
(the k smallest angles, ties to the lower index; the triangle whose smallest
barycentric weight is largest) and computes the same weights, so GPU and CPU
use the same neighbours at any direction, not only at cell centres.

Why the candidate lists are complete: if a cell lies within angle r of its
centre c and d_k(c) is the k-th nearest table angle from c, then for any
query q in the cell d_k(q) ≤ d_k(c) + r, so all of q's k nearest lie within
d_k(c) + 2r of c. A triangle holds q only if its circumscribed cap reaches
within r of c.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache, partial

import numpy as np

from render._errors import RenderError
from rig.geometry import angular_distance_deg, nearest_directions, spherical_triangulation

__all__ = ["CANDIDATES", "DirectionLookup", "build_lookup", "hemi_octahedral_cell"]

#: Candidates per grid cell (the shader's fixed loop length, a multiple of 4).
CANDIDATES = 16
# 64² cells: ~5 candidates per cell for H1 and nearest-4 (7 at 32²), built in 0.3 s.
_RESOLUTIONS = (64, 128, 256)
_METHOD_CODE = {"nearest": 0, "nearest4": 0, "barycentric": 1}


@dataclass(frozen=True)
class DirectionLookup:
    """What a shader needs to blend one direction table.

    Attributes
    ----------
    method : str
        ``"nearest"``, ``"nearest4"`` or ``"barycentric"``.
    code : int
        0 for nearest-k, 1 for barycentric (the shader's switch).
    k : int
        Neighbours blended (1, min(4, n) or 3).
    candidates : (R, R, CANDIDATES) int32
        Per cell (row = v, column = u of the grid) the candidate table
        indices (nearest-k) or triangle indices (barycentric), ascending, −1
        padded.
    table : (rows, 4) float32 array of texels
        Nearest-k: (n, 4) the table vectors (xyz, 0). Barycentric: (4·t, 4)
        per triangle its three inverse rows (xyz, 0) and its corners' table
        indices (as floats, 0).
    """

    method: str
    code: int
    k: int
    candidates: np.ndarray
    table: np.ndarray

    @property
    def resolution(self) -> int:
        return self.candidates.shape[0]


def hemi_octahedral_cell(vectors, resolution: int) -> np.ndarray:
    """(…, 2) int (column, row) of the grid cell holding each direction (z clamped to ≥ 0)."""
    d = np.asarray(vectors, dtype=np.float64).copy()
    d[..., 2] = np.maximum(d[..., 2], 0.0)
    p = d[..., :2] / np.sum(np.abs(d), axis=-1, keepdims=True)
    uv = np.stack([p[..., 0] + p[..., 1], p[..., 0] - p[..., 1]], axis=-1)
    return np.clip(np.floor((uv * 0.5 + 0.5) * resolution), 0, resolution - 1).astype(np.int64)


def _grid_directions(uv: np.ndarray) -> np.ndarray:
    """Unit directions of grid points (u, v) in [−1, 1]²."""
    px, py = (uv[..., 0] + uv[..., 1]) / 2, (uv[..., 0] - uv[..., 1]) / 2
    d = np.stack([px, py, 1.0 - np.abs(px) - np.abs(py)], axis=-1)
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def _cells(resolution: int) -> tuple[np.ndarray, np.ndarray]:
    """Centre directions (R·R, 3) and angular radii (R·R,) in degrees of the grid cells."""
    step = 2.0 / resolution
    edges = -1.0 + step * np.arange(resolution + 1)
    mids = (edges[:-1] + edges[1:]) / 2
    vv, uu = np.meshgrid(mids, mids, indexing="ij")
    centres = _grid_directions(np.stack([uu, vv], axis=-1)).reshape(-1, 3)
    radius = np.zeros(len(centres))
    for du in (-0.5, 0.0, 0.5):
        for dv in (-0.5, 0.0, 0.5):
            corner = _grid_directions(np.stack([uu + du * step, vv + dv * step], axis=-1))
            radius = np.maximum(radius, angular_distance_deg(corner.reshape(-1, 3), centres))
    # The corners and edge midpoints bound a small cell's extent; the margin covers curvature.
    return centres, radius * 1.25 + 1e-3


def _pack(close: np.ndarray, resolution: int) -> np.ndarray | None:
    """(cells, m) bool → (R, R, CANDIDATES) ascending indices, or None if a cell overflows."""
    if close.sum(axis=1).max() > CANDIDATES:
        return None
    out = np.full((close.shape[0], CANDIDATES), -1, np.int32)
    cells, indices = np.nonzero(close)
    slot = np.arange(len(cells)) - np.searchsorted(cells, cells)
    out[cells, slot] = indices
    return out.reshape(resolution, resolution, CANDIDATES)


def _nearest(table: np.ndarray, k: int, resolution: int) -> np.ndarray | None:
    centres, radius = _cells(resolution)
    d_k = nearest_directions(table, centres, k=k).angles_deg[:, -1]
    angles = angular_distance_deg(centres[:, None, :], table[None, :, :])
    return _pack(angles <= (d_k + 2 * radius)[:, None], resolution)


def _barycentric(centroid: np.ndarray, cap: np.ndarray, resolution: int) -> np.ndarray | None:
    centres, radius = _cells(resolution)
    angles = angular_distance_deg(centres[:, None, :], centroid[None, :, :])
    return _pack((angles <= cap[None, :] + radius[:, None]) | (cap >= 89.0)[None, :], resolution)


def build_lookup(table_vectors, method: str, *, index=None) -> DirectionLookup:
    """The lookup of a direction table for ``method`` (as ``direction_weights``).

    Lookups are kept for the last few tables, so renderers of one material
    share them.

    Parameters
    ----------
    table_vectors : (n, 3) array
        The measured directions.
    method : {"nearest", "nearest4", "barycentric"}
    index : (n,) int array, optional
        The index each table row stands for (a view table without its empty
        slots keeps the slots' own numbers); ``arange(n)`` by default.

    Raises
    ------
    RenderError
        An unknown method, or a table whose neighbourhoods are too crowded
        for the grid (more than :data:`CANDIDATES` candidates in a cell even
        at the finest resolution).
    """
    if method not in _METHOD_CODE:
        raise RenderError(f"interpolation method {method!r}: valid are {sorted(_METHOD_CODE)}")
    table = np.ascontiguousarray(table_vectors, dtype=np.float64)
    if table.ndim != 2 or table.shape[1] != 3 or len(table) == 0:
        raise RenderError(f"direction table: expected (n, 3) vectors, got shape {table.shape}")
    index = np.arange(len(table)) if index is None else np.asarray(index, dtype=np.int64)
    return _cached_lookup(table.tobytes(), method, index.tobytes())


@lru_cache(maxsize=8)
def _cached_lookup(table_bytes: bytes, method: str, index_bytes: bytes) -> DirectionLookup:
    table = np.frombuffer(table_bytes, np.float64).reshape(-1, 3)
    table = table / np.linalg.norm(table, axis=1, keepdims=True)
    index = np.frombuffer(index_bytes, np.int64)
    if method == "barycentric":
        try:
            mesh = spherical_triangulation(table)
        except ValueError as err:
            raise RenderError(f"barycentric interpolation: {err}; use method 'nearest4'") from err
        centroid = mesh.corners.sum(axis=1)
        centroid /= np.linalg.norm(centroid, axis=1, keepdims=True)
        cap = angular_distance_deg(mesh.corners, centroid[:, None, :]).max(axis=1)
        texels = np.zeros((len(centroid), 4, 4), np.float32)
        texels[:, :3, :3] = mesh.inverse
        texels[:, 3, :3] = index[mesh.owner]
        k, build = 3, partial(_barycentric, centroid, cap)
    else:
        k = 1 if method == "nearest" else min(4, len(table))
        texels = np.zeros((int(index.max()) + 1, 4), np.float32)
        texels[index, :3] = table
        build = partial(_nearest, table, k)
    for resolution in _RESOLUTIONS:
        candidates = build(resolution)
        if candidates is not None:
            break
    else:
        raise RenderError(
            f"{len(table)} directions are too crowded for {method!r} lookups "
            f"(> {CANDIDATES} candidates per cell at {_RESOLUTIONS[-1]}²); use 'nearest4'"
        )
    if method != "barycentric":
        candidates = np.where(candidates >= 0, index[np.maximum(candidates, 0)], -1)
    lookup = DirectionLookup(
        method, _METHOD_CODE[method], k, candidates.astype(np.int32), texels.reshape(-1, 4)
    )
    lookup.candidates.setflags(write=False)  # shared by every renderer of this table
    lookup.table.setflags(write=False)
    return lookup
