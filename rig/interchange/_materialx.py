"""A MaterialX document (``.mtlx``) of the fitted PBR material, with its textures.

A ``standard_surface`` whose inputs read the fitted maps through ``image`` nodes
(colour maps tagged ``srgb_texture``, the others raw) and a ``normalmap`` node; written
with the ``materialx`` package (``pip install 'btfrig[export]'``). What maps onto what:

- base colour → ``base_color`` (``base`` 1, ``metalness`` 0);
- roughness → ``specular_roughness``; specular → ``specular`` (weight);
- specular colour: standard_surface has no per-texel F0 scale, so ``specular_IOR`` is
  the IOR of the median fitted F0 (0.04 × specular colour);
- sheen colour, sheen roughness → ``sheen_color``, ``sheen_roughness`` (``sheen`` 1);
- anisotropy strength → ``specular_anisotropy``; direction φ → ``specular_rotation``
  (φ / 360°, the tangent turned towards the bitangent);
- the tangent-space normal map → ``normalmap`` → ``normal``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from rig.interchange._errors import InterchangeError
from rig.interchange._images import to_srgb
from rig.material import PbrMaps

__all__ = ["write_materialx"]


def _grey(values) -> np.ndarray:
    return np.round(np.clip(values, 0.0, 1.0) * 255.0).astype(np.uint8)


def _images(maps: PbrMaps) -> dict[str, tuple[np.ndarray, str, str]]:
    """file stem → (image, MaterialX type, colour space or "")."""

    def rgb(v):
        return np.repeat(v, 3, axis=-1) if v.shape[-1] == 1 else v

    return {
        "base_color": (to_srgb(rgb(maps.base_colour)), "color3", "srgb_texture"),
        "sheen_color": (to_srgb(rgb(maps.sheen_colour)), "color3", "srgb_texture"),
        "specular_roughness": (_grey(maps.roughness), "float", ""),
        "specular": (_grey(maps.specular), "float", ""),
        "sheen_roughness": (_grey(maps.sheen_roughness), "float", ""),
        "specular_anisotropy": (_grey(maps.anisotropy), "float", ""),
        "specular_rotation": (_grey((maps.anisotropy_deg % 180.0) / 360.0), "float", ""),
        "normal": (_grey((maps.normal.astype(np.float64) + 1.0) / 2.0), "vector3", ""),
    }


def write_materialx(folder, maps: PbrMaps, *, name: str = "btfrig_sample") -> Path:
    """Write ``folder/material.mtlx`` and its PNG textures into the existing ``folder``;
    returns the document's path. InterchangeError when ``materialx`` is not installed."""
    try:
        import MaterialX as mx  # noqa: N813 (the package's own usual name)
    except ImportError as err:
        raise InterchangeError(
            "the MaterialX export needs the materialx package: pip install 'btfrig[export]'"
        ) from err
    from PIL import Image

    folder = Path(folder)
    doc = mx.createDocument()
    shader = doc.addNode("standard_surface", f"{name}_surface", "surfaceshader")
    f0 = float(np.median(np.minimum(0.04 * maps.specular_colour, 0.99)))
    ior = (1.0 + np.sqrt(f0)) / (1.0 - np.sqrt(f0))
    for input_name, value in (("base", 1.0), ("metalness", 0.0), ("sheen", 1.0),
                              ("specular_IOR", float(ior))):  # fmt: skip
        shader.setInputValue(input_name, value, "float")
    for stem, (image, kind, colour_space) in _images(maps).items():
        file = f"{stem}.png"
        Image.fromarray(image).save(folder / file)
        node = doc.addNode("image", f"{stem}_image", kind)
        node.setInputValue("file", file, "filename")
        if colour_space:
            node.getInput("file").setColorSpace(colour_space)
        if stem == "normal":
            normal = doc.addNode("normalmap", "normal_map", "vector3")
            normal.addInput("in", "vector3").setConnectedNode(node)
            node = normal
        shader.addInput(stem, kind).setConnectedNode(node)
    material = doc.addMaterialNode(name, shader)
    material.setDocString("btfrig: the BTF's glTF PBR fit as a standard_surface")
    valid, message = doc.validate()
    if not valid:
        raise InterchangeError(f"MaterialX document of {name!r} does not validate: {message}")
    path = folder / "material.mtlx"
    mx.writeToXmlFile(doc, str(path))
    return path
