"""A binary glTF (``.glb``) of the sample with its maps as a PBR material.

The mesh is a plane of the sample's size (metres, glTF's unit; +Y up, the
sample's normal), or a mesh file with UVs: a glTF's is kept as it is, an
OBJ's or PLY's (mm, +Z up, as ``rig view`` reads them) turned into metres, +Y
up. The material's base colour is the albedo (sRGB), its normal texture the
OpenGL-convention normal map — glTF's own convention — at 8 bits (the image
library trimesh writes through holds no 16-bit RGB; the ``maps`` export has the
16-bit one), metallic 0, roughness 1.
"""

from __future__ import annotations

import json
import os
import struct
from pathlib import Path

import numpy as np

from rig.interchange._errors import InterchangeError
from rig.interchange._manifest import EXPORTED_BY, is_marked_manifest
from rig.interchange._maps import TextureMaps

__all__ = ["glb_generator", "is_export", "write_glb"]

#: The glb header (magic, version, length) and its first chunk's (length, type).
_GLB_HEADER = struct.Struct("<4sII")
_CHUNK_HEADER = struct.Struct("<I4s")
#: Largest JSON chunk read to find the generator (this project's are a few kB).
_JSON_LIMIT = 1 << 20


def _sample_plane(sample_mm: float):
    import trimesh

    half = sample_mm / 2000.0
    # Sample frame (x, y, z) → glTF (x, z, −y); the texel grid's row 0 (+y) is at −Z.
    vertices = np.array([[-half, 0, -half], [half, 0, -half], [half, 0, half], [-half, 0, half]])
    faces = np.array([[0, 2, 1], [0, 3, 2]])  # counter-clockwise seen from +Y
    # trimesh's UVs have v up (it flips them into glTF's top-left origin).
    uvs = np.array([[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]])
    mesh = trimesh.Trimesh(vertices, faces, process=False)
    return mesh, uvs


def _mesh_file(path: Path):
    import trimesh

    try:
        mesh = trimesh.load(path, force="mesh", process=False)
    except (ValueError, OSError) as err:
        raise InterchangeError(f"--mesh {path}: not a readable mesh ({err})") from err
    uvs = getattr(mesh.visual, "uv", None)
    if uvs is None or len(uvs) != len(mesh.vertices):
        raise InterchangeError(f"--mesh {path}: has no UV per vertex; the maps need UVs")
    if path.suffix.lower() not in (".gltf", ".glb"):
        x, y, z = np.asarray(mesh.vertices, dtype=np.float64).T
        mesh.vertices = np.stack([x, z, -y], axis=1) / 1000.0  # (x, y, z) mm → (x, z, −y) m
    return mesh, np.asarray(uvs)


def write_glb(path, maps: TextureMaps, *, sample_mm: float, mesh=None) -> Path:
    """Write ``path`` (.glb): a plane of ``sample_mm`` (or the mesh file ``mesh``)
    with the maps as a PBR material; returns the path."""
    import trimesh
    from PIL import Image

    path = Path(path)
    if path.suffix.lower() != ".glb":
        raise InterchangeError(f"{path}: a binary glTF needs the suffix .glb")
    geometry, uvs = _sample_plane(sample_mm) if mesh is None else _mesh_file(Path(mesh))
    normal8 = np.round(maps.normal / 257.0).astype(np.uint8)
    material = trimesh.visual.material.PBRMaterial(
        name="btfrig_sample",
        baseColorTexture=Image.fromarray(maps.albedo),
        normalTexture=Image.fromarray(normal8),
        metallicFactor=0.0,
        roughnessFactor=1.0,
    )
    geometry.visual = trimesh.visual.TextureVisuals(uv=uvs, material=material)

    def mark(tree: dict) -> None:
        tree.setdefault("asset", {})["generator"] = EXPORTED_BY

    scene = trimesh.Scene(geometry)
    path.write_bytes(trimesh.exchange.gltf.export_glb(scene, tree_postprocessor=mark))
    return path


def glb_generator(path: Path) -> str | None:
    """The ``asset.generator`` of the binary glTF at ``path``; None when it is none.

    Reads the header and at most 1 MiB of its JSON chunk, never following a link.
    """
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK)
    except OSError:
        return None
    try:
        head = os.read(fd, _GLB_HEADER.size + _CHUNK_HEADER.size)
        if len(head) != _GLB_HEADER.size + _CHUNK_HEADER.size:
            return None
        magic, _, _ = _GLB_HEADER.unpack_from(head)
        length, kind = _CHUNK_HEADER.unpack_from(head, _GLB_HEADER.size)
        if magic != b"glTF" or kind != b"JSON" or length > _JSON_LIMIT:
            return None
        tree = json.loads(os.read(fd, length))
    except (OSError, ValueError):
        return None
    finally:
        os.close(fd)
    asset = tree.get("asset") if isinstance(tree, dict) else None
    generator = asset.get("generator") if isinstance(asset, dict) else None
    return generator if isinstance(generator, str) else None


def is_export(path: Path) -> bool:
    """Whether ``path`` is an export this project wrote: a folder with a marked
    manifest, or a ``.glb`` it generated. Links are not followed."""
    if path.is_symlink():
        return False
    if path.is_dir():
        return is_marked_manifest(path)
    return path.suffix.lower() == ".glb" and glb_generator(path) == EXPORTED_BY
