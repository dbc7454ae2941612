"""A binary glTF (``.glb``) of the sample with its fitted PBR material.

Written directly (JSON chunk + binary chunk), because the extensions it needs —
KHR_materials_specular, KHR_materials_sheen, KHR_materials_anisotropy — are beyond what
trimesh writes. The mesh is the sample's plane in metres (+Y up, with a tangent per
vertex, so the normal and anisotropy textures have their frame), or a mesh file with
UVs (viewers derive its tangents). Textures are :mod:`rig.interchange._pbr_textures`.
"""

from __future__ import annotations

import json
import struct
from pathlib import Path

import numpy as np

from rig.interchange._errors import InterchangeError
from rig.interchange._gltf import _mesh_file
from rig.interchange._pbr_textures import PbrTextures

__all__ = ["EXTENSIONS", "write_pbr_glb"]

EXTENSIONS = ("KHR_materials_specular", "KHR_materials_sheen", "KHR_materials_anisotropy")
_FLOAT, _UINT = 5126, 5125
_ARRAY, _ELEMENTS = 34962, 34963


class _Builder:
    """Buffer views and accessors appended to one binary buffer (4-byte aligned)."""

    def __init__(self) -> None:
        self.blob = bytearray()
        self.views: list[dict] = []
        self.accessors: list[dict] = []

    def view(self, data: bytes, target: int | None = None) -> int:
        self.blob.extend(b"\0" * (-len(self.blob) % 4))
        view = {"buffer": 0, "byteOffset": len(self.blob), "byteLength": len(data)}
        if target is not None:
            view["target"] = target
        self.blob.extend(data)
        self.views.append(view)
        return len(self.views) - 1

    def accessor(self, values: np.ndarray, kind: str, *, target: int, bounds: bool = False) -> int:
        component = _UINT if values.dtype == np.uint32 else _FLOAT
        accessor = {
            "bufferView": self.view(values.tobytes(), target), "componentType": component,
            "count": len(values), "type": kind,
        }  # fmt: skip
        if bounds:
            accessor["min"] = values.min(axis=0).tolist()
            accessor["max"] = values.max(axis=0).tolist()
        self.accessors.append(accessor)
        return len(self.accessors) - 1


def _plane(sample_mm: float):
    """Positions, normals, glTF UVs (v down), tangents and indices of the sample's plane."""
    half = sample_mm / 2000.0
    # Sample frame (x, y, z) → glTF (x, z, −y): texel row 0 (+y) lies at −Z, image top.
    positions = np.array([[-half, 0, -half], [half, 0, -half], [half, 0, half], [-half, 0, half]])
    uvs = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    normals = np.tile([0.0, 1.0, 0.0], (4, 1))
    # bitangent = normal × tangent · w = +Y × +X = −Z: the sample's +y, the image's up
    tangents = np.tile([1.0, 0.0, 0.0, 1.0], (4, 1))
    indices = np.array([0, 2, 1, 0, 3, 2])  # counter-clockwise seen from +Y
    return positions, normals, uvs, tangents, indices


def _from_file(path: Path):
    mesh, uvs = _mesh_file(path)
    uvs = np.column_stack([uvs[:, 0], 1.0 - uvs[:, 1]])  # trimesh's v up → glTF's v down
    return mesh.vertices, mesh.vertex_normals, uvs, None, mesh.faces.reshape(-1)


def write_pbr_glb(
    path,
    textures: PbrTextures,
    *,
    sample_mm: float,
    mesh=None,
    name: str = "btfrig_sample",
    manifest: dict | None = None,
) -> Path:
    """Write ``path`` (.glb): a plane of ``sample_mm`` (or the mesh file ``mesh``) with the
    fitted material: base colour, metallic 0 and roughness, normal texture, and the
    specular, sheen and anisotropy extensions, each from its texture. ``manifest``
    (JSON-able: the source, the fit's error…) goes into ``asset.extras.btfrig``."""
    path = Path(path)
    if path.suffix.lower() != ".glb":
        raise InterchangeError(f"{path}: a binary glTF needs the suffix .glb")
    positions, normals, uvs, tangents, indices = (
        _plane(sample_mm) if mesh is None else _from_file(Path(mesh))
    )
    b = _Builder()
    attributes = {
        "POSITION": b.accessor(
            np.asarray(positions, np.float32), "VEC3", target=_ARRAY, bounds=True
        ),
        "NORMAL": b.accessor(np.asarray(normals, np.float32), "VEC3", target=_ARRAY),
        "TEXCOORD_0": b.accessor(np.asarray(uvs, np.float32), "VEC2", target=_ARRAY),
    }  # fmt: skip
    if tangents is not None:
        attributes["TANGENT"] = b.accessor(np.asarray(tangents, np.float32), "VEC4", target=_ARRAY)
    index = b.accessor(np.asarray(indices, np.uint32), "SCALAR", target=_ELEMENTS)
    names = list(textures.images)
    images = [{"bufferView": b.view(textures.png(n)), "mimeType": "image/png", "name": n}
              for n in names]  # fmt: skip

    def texture(n: str) -> dict:
        return {"index": names.index(n)}

    material = {
        "name": name,
        "pbrMetallicRoughness": {
            "baseColorTexture": texture("base_colour"),
            "metallicFactor": 0.0, "roughnessFactor": 1.0,
            "metallicRoughnessTexture": texture("metallic_roughness"),
        },
        "normalTexture": texture("normal"),
        "extensions": {
            "KHR_materials_specular": {
                "specularFactor": 1.0, "specularTexture": texture("specular"),
                "specularColorFactor": [textures.specular_colour_factor] * 3,
                "specularColorTexture": texture("specular"),
            },
            "KHR_materials_sheen": {
                "sheenColorFactor": [1.0, 1.0, 1.0], "sheenColorTexture": texture("sheen"),
                "sheenRoughnessFactor": 1.0, "sheenRoughnessTexture": texture("sheen"),
            },
            "KHR_materials_anisotropy": {
                "anisotropyStrength": 1.0, "anisotropyRotation": 0.0,
                "anisotropyTexture": texture("anisotropy"),
            },
        },
    }  # fmt: skip
    document = {
        "asset": {"version": "2.0", "generator": "btfrig", "extras": {"btfrig": manifest or {}}},
        "extensionsUsed": list(EXTENSIONS),
        "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0, "name": name}],
        "meshes": [{"name": name, "primitives": [
            {"attributes": attributes, "indices": index, "material": 0}]}],
        "materials": [material],
        "samplers": [{"magFilter": 9729, "minFilter": 9987, "wrapS": 10497, "wrapT": 10497}],
        "textures": [{"sampler": 0, "source": i} for i in range(len(names))],
        "images": images,
        "accessors": b.accessors, "bufferViews": b.views,
        "buffers": [{"byteLength": len(b.blob) + (-len(b.blob) % 4)}],
    }  # fmt: skip
    path.write_bytes(_glb(document, bytes(b.blob)))
    return path


def _glb(document: dict, blob: bytes) -> bytes:
    """The GLB container: header, JSON chunk (space-padded), BIN chunk (zero-padded)."""
    text = json.dumps(document, separators=(",", ":")).encode()
    text += b" " * (-len(text) % 4)
    blob += b"\0" * (-len(blob) % 4)
    total = 12 + 8 + len(text) + 8 + len(blob)
    return (struct.pack("<4sII", b"glTF", 2, total) + struct.pack("<I4s", len(text), b"JSON")
            + text + struct.pack("<I4s", len(blob), b"BIN\0") + blob)  # fmt: skip
