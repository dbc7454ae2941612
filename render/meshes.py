"""Meshes the renderer draws a material on: built-in shapes and files with UVs.

Units: positions are mm. UVs are mm of surface as well — one UV unit spans one
mm along the surface on average — so the renderer places the sample by its
measured size: the sample's texture coordinate is ``uv / tile_mm``, one repeat
of the sample per ``tile_mm`` mm, and ``tile_mm`` = the sample's side shows it
at true scale. Built-in shapes carry arc lengths as UVs (exact along the
parameter lines); a file's UV layout is kept and scaled by one factor, the
square root of its surface area over its UV area.

Every mesh carries per-vertex tangent frames computed from its UVs
(:func:`render._tangents.tangent_frames`); triangles with no area in space or
in UV and vertices whose frame had to come from the normal alone are counted
on the mesh.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh

from render._cloth import drape
from render._tangents import tangent_frames, vertex_normals
from rig.errors import RigError

__all__ = [
    "BUILT_IN",
    "Mesh",
    "MeshError",
    "cloth",
    "cylinder",
    "load_mesh",
    "merged",
    "mesh_by_name",
    "mesh_from_arrays",
    "plane",
    "sphere",
    "torus",
]


class MeshError(RigError):
    """A mesh cannot be read or built; the message names the file or the field."""


@dataclass(frozen=True, eq=False)  # identity equality: arrays have no single truth value
class Mesh:
    """A triangle mesh with UVs and tangent frames, read-only.

    Attributes
    ----------
    positions : (V, 3) float32, mm
    normals : (V, 3) float32, unit
    uvs : (V, 2) float32, mm of surface (see the module's docstring)
    tangents : (V, 4) float32
        xyz a unit tangent along +u, orthogonal to the normal; w = ±1 so that
        the bitangent (along +v) is ``w · cross(normal, tangent)``.
    faces : (F, 3) uint32, counter-clockwise seen from the front
    name : str
        The built-in's name or the file it came from.
    degenerate_faces : int
        Triangles with no area in space or in UV (left out of the frames).
    fallback_frames : int
        Vertices whose tangent came from the normal alone.
    """

    positions: np.ndarray
    normals: np.ndarray
    uvs: np.ndarray
    tangents: np.ndarray
    faces: np.ndarray
    name: str
    degenerate_faces: int = 0
    fallback_frames: int = 0

    def __post_init__(self) -> None:
        columns = {"positions": 3, "normals": 3, "uvs": 2, "tangents": 4, "faces": 3}
        n_vertices = len(np.asarray(self.positions))
        for field, width in columns.items():
            dtype = np.uint32 if field == "faces" else np.float32
            array = np.array(getattr(self, field), dtype=dtype)
            if array.ndim != 2 or array.shape[1] != width:
                raise MeshError(
                    f"mesh {self.name!r}: {field} has shape {array.shape}; expected (N, {width})"
                )
            if field != "faces" and len(array) != n_vertices:
                raise MeshError(
                    f"mesh {self.name!r}: {field} has {len(array)} rows but positions has "
                    f"{n_vertices}; every per-vertex array needs one row per vertex"
                )
            if not np.isfinite(array).all():
                raise MeshError(f"mesh {self.name!r}: {field} holds NaN or inf values")
            array.flags.writeable = False
            object.__setattr__(self, field, array)
        if len(self.faces) == 0:
            raise MeshError(f"mesh {self.name!r} has no faces; a mesh needs at least one triangle")
        if int(self.faces.max()) >= n_vertices:
            raise MeshError(
                f"mesh {self.name!r}: faces refer to vertex {int(self.faces.max())} but there "
                f"are only {n_vertices} vertices"
            )


def mesh_from_arrays(
    positions: np.ndarray,
    uvs: np.ndarray,
    faces: np.ndarray,
    *,
    name: str,
    normals: np.ndarray | None = None,
) -> Mesh:
    """A :class:`Mesh` with tangent frames (and normals, when not given) computed.

    Parameters
    ----------
    positions : (V, 3) float, mm
    uvs : (V, 2) float, mm of surface
    faces : (F, 3) int, counter-clockwise seen from the front
    name : str
    normals : (V, 3) float, unit, optional
        Area-weighted face normals when left out.
    """
    positions = np.asarray(positions, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64)
    if normals is None:
        normals, _ = vertex_normals(positions, faces)
    frames = tangent_frames(positions, normals, uvs, faces)
    return Mesh(
        positions=positions,
        normals=normals,
        uvs=uvs,
        tangents=frames.tangents,
        faces=faces,
        name=name,
        degenerate_faces=int(frames.degenerate_faces.sum()),
        fallback_frames=int(frames.fallback.sum()),
    )


def merged(parts, *, name: str) -> Mesh:
    """One mesh of several (a floor and what stands on it), their vertices and faces in turn."""
    parts = list(parts)
    offsets = np.cumsum([0] + [len(part.positions) for part in parts[:-1]])
    return Mesh(
        **{field: np.vstack([getattr(part, field) for part in parts])
           for field in ("positions", "normals", "uvs", "tangents")},
        faces=np.vstack([part.faces + offset for part, offset in zip(parts, offsets, strict=True)]),
        name=name,
        degenerate_faces=sum(part.degenerate_faces for part in parts),
        fallback_frames=sum(part.fallback_frames for part in parts),
    )  # fmt: skip


def _grid_faces(n_u: int, n_v: int) -> np.ndarray:
    """Two counter-clockwise triangles per cell of an (n_u + 1) × (n_v + 1) vertex grid."""
    index = np.arange((n_u + 1) * (n_v + 1)).reshape(n_v + 1, n_u + 1)
    a, b = index[:-1, :-1].ravel(), index[:-1, 1:].ravel()
    d, c = index[1:, :-1].ravel(), index[1:, 1:].ravel()
    return np.concatenate([np.stack([a, b, c], axis=1), np.stack([a, c, d], axis=1)])


def _parametric(
    name: str,
    surface: Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]],
    u_mm: np.ndarray,
    v_mm: np.ndarray,
) -> Mesh:
    """A grid over (u, v) in mm of arc; ``surface`` gives positions and unit normals.

    Cells that collapse to a point or a line (a sphere's poles) are dropped.
    """
    u, v = np.meshgrid(u_mm, v_mm)
    positions, normals = surface(u, v)
    positions, normals = positions.reshape(-1, 3), normals.reshape(-1, 3)
    faces = _grid_faces(len(u_mm) - 1, len(v_mm) - 1)
    corners = positions[faces]
    area2 = np.linalg.norm(
        np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1
    )
    faces = faces[area2 > 1e-9 * float(np.ptp(positions, axis=0).max()) ** 2]
    used, faces = np.unique(faces, return_inverse=True)
    uvs = np.stack([u.ravel(), v.ravel()], axis=1)
    return mesh_from_arrays(
        positions[used], uvs[used], faces.reshape(-1, 3), name=name, normals=normals[used]
    )


def _check_sizes(shape: str, **sizes: float) -> None:
    for field, value in sizes.items():
        if not (np.isfinite(value) and value > 0):
            raise MeshError(f"{shape}: {field} is {value}; it must be a positive number of mm")


def _check_segments(shape: str, segments: int, least: int) -> None:
    if int(segments) != segments or segments < least:
        raise MeshError(f"{shape}: segments is {segments}; it must be a whole number ≥ {least}")


def plane(*, size_mm: float = 100.0, segments: int = 1) -> Mesh:
    """A square in z = 0 facing +z, centred on the origin; u along +x, v along +y."""
    _check_sizes("plane", size_mm=size_mm)
    _check_segments("plane", segments, 1)
    edge = np.linspace(0.0, size_mm, segments + 1)

    def surface(u: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        positions = np.stack([u - size_mm / 2, v - size_mm / 2, np.zeros_like(u)], axis=-1)
        return positions, np.broadcast_to([0.0, 0.0, 1.0], positions.shape)

    return _parametric("plane", surface, edge, edge)


def sphere(*, radius_mm: float = 50.0, segments: int = 48) -> Mesh:
    """A UV sphere centred on the origin: u along the equator (east), v pole to pole (north).

    ``segments`` rings from pole to pole and twice as many around; u = r·longitude,
    v = r·(latitude + 90°).
    """
    _check_sizes("sphere", radius_mm=radius_mm)
    _check_segments("sphere", segments, 3)
    longitude = np.linspace(0.0, 2 * np.pi, 2 * segments + 1)
    latitude = np.linspace(-np.pi / 2, np.pi / 2, segments + 1)

    def surface(u: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        lon, lat = u / radius_mm, v / radius_mm - np.pi / 2
        normals = np.stack(
            [np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)], axis=-1
        )
        return radius_mm * normals, normals

    return _parametric("sphere", surface, radius_mm * longitude, radius_mm * (latitude + np.pi / 2))


def cylinder(*, radius_mm: float = 30.0, height_mm: float = 100.0, segments: int = 48) -> Mesh:
    """An open tube about the z axis, centred on the origin: u around (r·angle), v along +z."""
    _check_sizes("cylinder", radius_mm=radius_mm, height_mm=height_mm)
    _check_segments("cylinder", segments, 3)
    angle = np.linspace(0.0, 2 * np.pi, 2 * segments + 1)
    rings = max(1, round(segments * height_mm / (2 * np.pi * radius_mm)))

    def surface(u: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        phi = u / radius_mm
        normals = np.stack([np.cos(phi), np.sin(phi), np.zeros_like(phi)], axis=-1)
        positions = radius_mm * normals
        positions[..., 2] = v - height_mm / 2
        return positions, normals

    return _parametric(
        "cylinder", surface, radius_mm * angle, np.linspace(0.0, height_mm, rings + 1)
    )


def torus(*, major_mm: float = 50.0, minor_mm: float = 20.0, segments: int = 48) -> Mesh:
    """A ring torus in the xy plane about the origin.

    u = major·(angle about z), v = minor·(angle about the tube, from the outer equator
    towards +z).
    """
    _check_sizes("torus", major_mm=major_mm, minor_mm=minor_mm)
    _check_segments("torus", segments, 3)
    if minor_mm >= major_mm:
        raise MeshError(
            f"torus: minor_mm {minor_mm} must be smaller than major_mm {major_mm} (a ring torus)"
        )
    around = np.linspace(0.0, 2 * np.pi, 2 * segments + 1)
    tube = np.linspace(0.0, 2 * np.pi, segments + 1)

    def surface(u: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        phi, psi = u / major_mm, v / minor_mm
        normals = np.stack(
            [np.cos(psi) * np.cos(phi), np.cos(psi) * np.sin(phi), np.sin(psi)], axis=-1
        )
        centre = np.stack([major_mm * np.cos(phi), major_mm * np.sin(phi), np.zeros_like(phi)], -1)
        return centre + minor_mm * normals, normals

    return _parametric("torus", surface, major_mm * around, minor_mm * tube)


@functools.lru_cache(maxsize=4)
def cloth(*, size_mm: float = 400.0, sphere_radius_mm: float = 80.0, segments: int = 48) -> Mesh:
    """A square cloth draped over a sphere that rests on a table, with folds.

    The sphere's centre is the origin and the table is z = −``sphere_radius_mm``;
    neither is part of the mesh. The cloth is settled by position-based dynamics
    (:func:`render._cloth.drape`, deterministic, about a second); its UVs are its
    rest grid in mm, so the sample is not stretched where the cloth is not.
    """
    _check_sizes("cloth", size_mm=size_mm, sphere_radius_mm=sphere_radius_mm)
    _check_segments("cloth", segments, 2)
    positions = drape(size_mm=size_mm, sphere_radius_mm=sphere_radius_mm, segments=segments)
    edge = np.linspace(0.0, size_mm, segments + 1)
    u, v = np.meshgrid(edge, edge)
    uvs = np.stack([u.ravel(), v.ravel()], axis=1)
    return mesh_from_arrays(positions, uvs, _grid_faces(segments, segments), name="cloth")


BUILT_IN: dict[str, Callable[[], Mesh]] = {
    "plane": plane,
    "sphere": sphere,
    "cylinder": cylinder,
    "torus": torus,
    "cloth": cloth,
}

# Formats trimesh reads with texture coordinates (STL is read only to say it has none).
_FORMATS = (".obj", ".ply", ".gltf", ".glb", ".stl")
_GLTF = (".gltf", ".glb")
# glTF's axes (+Y up, +Z towards the viewer) → the renderer's (+Z up): (X, Y, Z) → (X, −Z, Y).
_Y_UP_TO_Z_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])


def load_mesh(path: str | Path, *, mm_per_unit: float | None = None) -> Mesh:
    """Read an OBJ, PLY, glTF/GLB or STL file with UVs through trimesh.

    A glTF is in metres with +Y up, as the format defines: it is read into mm
    with +Z up (``rig export gltf``'s plane comes back as the sample, in the
    xy-plane). OBJ, PLY and STL define no unit and are read as mm, +Z up.

    Parameters
    ----------
    path : path of the file
    mm_per_unit : float, optional
        Length of one of the file's units in mm (default: 1000 for glTF, else 1).

    Returns
    -------
    Mesh
        Normals from the file when it has them, else area-weighted; UVs scaled to
        mm of surface (see the module's docstring); tangents from the UVs.

    Raises
    ------
    MeshError
        The file is missing, unreadable, of an unknown format, or has no UVs.
    """
    path = Path(path)
    gltf = path.suffix.lower() in _GLTF
    if mm_per_unit is None:
        mm_per_unit = 1000.0 if gltf else 1.0
    _check_sizes(str(path), mm_per_unit=mm_per_unit)
    if path.suffix.lower() not in _FORMATS:
        raise MeshError(
            f"{path}: unknown mesh format {path.suffix!r}; readable: {', '.join(_FORMATS)}"
        )
    if not path.is_file():
        raise MeshError(f"{path}: no such mesh file")
    try:
        loaded = trimesh.load(path, force="mesh", process=False)
    except Exception as err:  # trimesh's readers raise many types; all mean "unreadable"
        raise MeshError(f"{path}: cannot read the mesh: {err}") from err
    if not isinstance(loaded, trimesh.Trimesh) or len(loaded.faces) == 0:
        raise MeshError(f"{path}: the file holds no triangles")
    uvs = getattr(loaded.visual, "uv", None)
    if uvs is None or len(uvs) != len(loaded.vertices):
        raise MeshError(
            f"{path}: the mesh has no texture coordinates (UVs), and the renderer maps the "
            "sample through them; export it with UVs (OBJ, PLY, glTF) or use a built-in mesh: "
            f"{', '.join(BUILT_IN)}"
        )
    turn = _Y_UP_TO_Z_UP if gltf else np.eye(3)
    positions = np.asarray(loaded.vertices, dtype=np.float64) @ turn.T * mm_per_unit
    faces = np.asarray(loaded.faces, dtype=np.int64)
    uvs = np.asarray(uvs, dtype=np.float64)
    corners, uv_corners = positions[faces], uvs[faces]
    area = np.linalg.norm(
        np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1
    ).sum()
    uv_edges1, uv_edges2 = uv_corners[:, 1] - uv_corners[:, 0], uv_corners[:, 2] - uv_corners[:, 0]
    uv_area = np.abs(uv_edges1[:, 0] * uv_edges2[:, 1] - uv_edges2[:, 0] * uv_edges1[:, 1]).sum()
    if not (np.isfinite(uv_area) and uv_area > 0 and area > 0):
        raise MeshError(f"{path}: the UVs (or the surface) span no area; nothing can be mapped")
    # The file's normals (or trimesh's) when every one is unit; ours, with fallbacks, if not.
    normals = np.asarray(loaded.vertex_normals, dtype=np.float64) @ turn.T
    if normals.shape != positions.shape or not np.allclose(
        np.linalg.norm(normals, axis=1), 1.0, atol=1e-3
    ):
        normals = None
    return mesh_from_arrays(
        positions, uvs * np.sqrt(area / uv_area), faces, name=str(path), normals=normals
    )


def mesh_by_name(spec: str | Path) -> Mesh:
    """A built-in mesh by name (``plane``, ``sphere``, …) or a mesh file by path."""
    if str(spec) in BUILT_IN:
        return BUILT_IN[str(spec)]()
    path = Path(spec)
    if path.suffix.lower() in _FORMATS:
        return load_mesh(path)
    raise MeshError(
        f"mesh {str(spec)!r} is neither a built-in ({', '.join(BUILT_IN)}) nor a mesh file "
        f"({', '.join(_FORMATS)})"
    )
