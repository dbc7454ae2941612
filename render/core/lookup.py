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

Every cell lists the same number of candidates, the table's longest list
(cells that need fewer take the next closest ones, which never win), so the
shader's loop has a fixed length known when it is compiled: no padding to
test, no early exit, which a software rasteriser runs fastest. The grid is the
one of 64² and 128² with the shorter lists (64² on a tie).

Why the candidate lists are complete: if a cell lies within angle r of its
centre c and d_k(c) is the k-th nearest table angle from c, then for any
query q in the cell d_k(q) ≤ d_k(c) + r, so all of q's k nearest lie within
d_k(c) + 2r of c. A triangle holds q only if its circumscribed cap reaches
within r of c, and only if each of its three edge planes (the rows of its
inverse, w_i = row_i · q ≥ 0) has q on its inner side: the row lies within
90° + r of c.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache, partial

import numpy as np

from render._errors import RenderError
from rig.geometry import angular_distance_deg, spherical_triangulation

__all__ = [
    "BLEND_METHODS",
    "MAX_CANDIDATES",
    "DirectionLookup",
    "build_lookup",
    "hemi_octahedral_cell",
]

#: How measured directions are blended at a query (``processing.btf.interpolate``).
BLEND_METHODS = ("nearest", "nearest4", "barycentric")
#: Longest candidate list a lookup may have (the shader's loop length).
MAX_CANDIDATES = 16
# Nearest-4 lists: H1 9 candidates at 64² and at 128² (27 view slots: 10, 9); 256² would save
# one more at 16× the memory and build time.
_RESOLUTIONS = (64, 128)
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
    candidates : (R, R, L) int32
        Per cell (row = v, column = u of the grid) the same number L of
        candidate table indices (nearest-k) or triangle indices
        (barycentric), ascending.
    table : (rows, 4) float32 array of texels
        Nearest-k: (n, 4) the table vectors (xyz, index). Barycentric:
        (3·t, 4) per triangle the three rows of its inverse, each with its
        corner's table index in w (w_i = row_i · q is corner i's weight).
    """

    method: str
    code: int
    k: int
    candidates: np.ndarray
    table: np.ndarray

    @property
    def resolution(self) -> int:
        return self.candidates.shape[0]

    @property
    def length(self) -> int:
        """Candidates per cell, L."""
        return self.candidates.shape[2]

    def cell_texels(self) -> np.ndarray:
        """(L·m, R, R, 4) float32: layer i·m + j holds texel j of each cell's candidate i
        (m = 1 texel per direction, 3 rows per triangle), so the shader reads a
        cell's candidates without a second lookup."""
        per = 3 if self.code == 1 else 1
        texels = self.table.reshape(-1, per, 4)[self.candidates]  # (R, R, L, per, 4)
        r = self.resolution
        return np.ascontiguousarray(texels.reshape(r, r, -1, 4).transpose(2, 0, 1, 3))


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


def _shortest_lists(reach_of, resolution: int) -> np.ndarray:
    """(R, R, L) ascending candidate indices: each cell's L smallest reaches, L the
    longest list any cell needs. ``reach_of(centres)`` gives (cells, m) reaches in
    degrees: candidate j is needed in a cell only where its reach ≤ the cell's radius."""
    centres, radius = _cells(resolution)
    counts, order = [], []
    for lo in range(0, len(centres), 4096):  # bounded memory at 256²
        reach = reach_of(centres[lo : lo + 4096])
        counts.append((reach <= radius[lo : lo + 4096, None]).sum(axis=1))
        keep = min(MAX_CANDIDATES + 1, reach.shape[1])
        part = np.argpartition(reach, keep - 1, axis=1)[:, :keep]
        by_reach = np.argsort(np.take_along_axis(reach, part, axis=1), axis=1, kind="stable")
        order.append(np.take_along_axis(part, by_reach, axis=1))
    length = int(np.concatenate(counts).max())
    nearest = np.sort(np.concatenate(order)[:, :length], axis=1)
    return nearest.astype(np.int32).reshape(resolution, resolution, -1)


def _pair_angles_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(m, n) angles in degrees between unit vectors a (m, 3) and b (n, 3): one matrix
    product (arccos is exact to ~1e-6° here, far inside the cells' margin)."""
    return np.rad2deg(np.arccos(np.clip(a @ b.T, -1.0, 1.0)))


def _nearest_reach(table: np.ndarray, k: int, centres: np.ndarray) -> np.ndarray:
    angles = _pair_angles_deg(centres, table)
    d_k = np.partition(angles, k - 1, axis=1)[:, k - 1 : k]
    return (angles - d_k) / 2


def _holds_every_direction(mesh) -> bool:
    """Whether the triangles' hull holds the origin, so every direction lies in a triangle."""
    corners = mesh.corners
    normal = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    offset = np.einsum("ti,ti->t", normal, corners[:, 0])
    inside = corners.reshape(-1, 3).mean(axis=0) @ normal.T - offset
    return bool(np.all((np.abs(offset) > 1e-9) & (np.sign(inside) == -np.sign(offset))))


def _barycentric_reach(mesh):
    """``reach_of(centres)`` for the triangles of ``mesh``."""
    centroid = mesh.corners.sum(axis=1)
    centroid /= np.linalg.norm(centroid, axis=1, keepdims=True)
    cap = angular_distance_deg(mesh.corners, centroid[:, None, :]).max(axis=1)
    unbounded = cap >= 89.0  # a cap this wide bounds nothing
    # The CPU's choice may lie outside every triangle unless they hold every direction.
    edges = _holds_every_direction(mesh)
    rows = mesh.inverse / np.linalg.norm(mesh.inverse, axis=2, keepdims=True)

    def reach_of(centres: np.ndarray) -> np.ndarray:
        reach = _pair_angles_deg(centres, centroid) - cap
        reach[:, unbounded] = -np.inf
        if not edges:
            return reach
        # angle(row, c) − 90° = −asin(row · c): the edge plane the cell is furthest outside.
        cosines = np.minimum.reduce([centres @ rows[:, i].T for i in range(3)])
        return np.maximum(reach, -np.rad2deg(np.arcsin(np.clip(cosines, -1.0, 1.0))))

    return reach_of


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
        for the grid (more than :data:`MAX_CANDIDATES` candidates in a cell
        even at the finest resolution).
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
        texels = np.zeros((len(mesh.inverse), 3, 4), np.float32)
        texels[:, :, :3] = mesh.inverse
        texels[:, :, 3] = index[mesh.owner]
        k, reach_of = 3, _barycentric_reach(mesh)
    else:
        k = 1 if method == "nearest" else min(4, len(table))
        texels = np.zeros((int(index.max()) + 1, 4), np.float32)
        texels[index, :3] = table
        texels[index, 3] = index
        reach_of = partial(_nearest_reach, table, k)
    lists = (_shortest_lists(reach_of, resolution) for resolution in _RESOLUTIONS)
    candidates = min(lists, key=lambda c: c.shape[2])
    if candidates.shape[2] > MAX_CANDIDATES:
        raise RenderError(
            f"{len(table)} directions are too crowded for {method!r} lookups "
            f"(> {MAX_CANDIDATES} candidates per cell at {_RESOLUTIONS[-1]}²); use 'nearest4'"
        )
    if method != "barycentric":
        candidates = index[candidates]
    lookup = DirectionLookup(
        method, _METHOD_CODE[method], k, candidates.astype(np.int32), texels.reshape(-1, 4)
    )
    lookup.candidates.setflags(write=False)  # shared by every renderer of this table
    lookup.table.setflags(write=False)
    return lookup
