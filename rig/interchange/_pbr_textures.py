"""The fitted PBR maps as the 8-bit textures glTF, MaterialX and the web viewer read.

One packing for every export, the glTF extensions' own:

- ``base_colour``: RGB base colour, sRGB;
- ``metallic_roughness``: G roughness, B metallic (0), linear;
- ``normal``: RGB (n + 1) / 2, tangent space, OpenGL convention (+Y up), linear;
- ``specular``: RGB specular colour / ``specular_colour_factor`` (sRGB), A specular (linear);
- ``sheen``: RGB sheen colour (sRGB), A sheen roughness (linear);
- ``anisotropy``: RG (cos φ, sin φ) mapped to [0, 1], B strength, linear.

On the flat sample the tangent frame is the sample frame (tangent +x, bitangent +y,
normal +z) and texel row 0 is the image's top row (+y), as in the ``maps`` export.
"""

from __future__ import annotations

import io
from dataclasses import dataclass

import numpy as np

from rig.interchange._images import to_srgb
from rig.material import PbrMaps

__all__ = ["PbrTextures", "pbr_textures"]


@dataclass(frozen=True)
class PbrTextures:
    """The packed textures (name → (N, N, 3|4) uint8) and the factors they go with.

    ``specular_colour_factor``: glTF's ``specularColorFactor`` (grey), the largest
    fitted specular colour, so that the texture holds specular colour / factor ≤ 1.
    """

    images: dict[str, np.ndarray]
    specular_colour_factor: float

    def png(self, name: str) -> bytes:
        """One texture encoded as PNG."""
        from PIL import Image

        buffer = io.BytesIO()
        Image.fromarray(self.images[name]).save(buffer, format="PNG", optimize=True)
        return buffer.getvalue()


def _rgb(values: np.ndarray) -> np.ndarray:
    return np.repeat(values, 3, axis=-1) if values.shape[-1] == 1 else values


def _unit8(values) -> np.ndarray:
    return np.round(np.clip(values, 0.0, 1.0) * 255.0).astype(np.uint8)


def pbr_textures(maps: PbrMaps) -> PbrTextures:
    """Pack ``maps`` into the textures of the table above."""
    n = maps.size
    factor = max(float(maps.specular_colour.max(initial=0.0)), 1e-6)
    phi = np.deg2rad(maps.anisotropy_deg.astype(np.float64))
    zero = np.zeros((n, n))
    images = {
        "base_colour": to_srgb(_rgb(maps.base_colour)),
        "metallic_roughness": _unit8(np.dstack([zero, maps.roughness, zero])),
        "normal": _unit8((maps.normal.astype(np.float64) + 1.0) / 2.0),
        "specular": np.dstack([
            to_srgb(np.repeat((maps.specular_colour / factor)[..., None], 3, axis=-1)),
            _unit8(maps.specular),
        ]),
        "sheen": np.dstack([to_srgb(_rgb(maps.sheen_colour)), _unit8(maps.sheen_roughness)]),
        "anisotropy": _unit8(
            np.dstack([(np.cos(phi) + 1) / 2, (np.sin(phi) + 1) / 2, maps.anisotropy])
        ),
    }  # fmt: skip
    return PbrTextures(images, factor)
