"""The MDF on the surface program (seed 001 §4): the MDF texture, which the
silhouette peel shares, and for the shadows (``shaders/mdf_shadow.glsl``) its
uniforms and the ambient term's texture."""

from __future__ import annotations

from dataclasses import dataclass

import moderngl
import numpy as np

from render._errors import RenderError
from render.points.ambient import upload_ambient
from render.points.mdf import GRAZING_DEG, MdfTexture, mdf_table, upload_mdf

__all__ = ["MdfShading", "mdf_shading"]


@dataclass
class MdfShading:
    """``texture`` the MDF; ``ambient`` L_a per view slot (None: no ambient term);
    ``uniforms`` of ``mdf_shadow.glsl`` (``mdf_scale`` s, ``mdf_depth`` d_max in mm of
    the sample, ``max_slant`` the grazing clamp, ``ambient`` the skylight fraction)."""

    texture: MdfTexture
    ambient: moderngl.TextureArray | None
    uniforms: dict[str, float]

    @property
    def base_depth(self) -> float:
        """s · d_max: the mesostructure's depth below the surfaces, scene units."""
        return self.uniforms["mdf_scale"] * self.uniforms["mdf_depth"]

    def defines(self) -> dict[str, int]:
        """The shader constants of ``mdf.glsl`` and ``mdf_shadow.glsl``'s AMBIENT."""
        return {**self.texture.defines(), "AMBIENT": int(self.ambient is not None)}

    def textures(self) -> dict[str, moderngl.TextureArray]:
        """Sampler name → texture."""
        named = {"mdf_distance": self.texture.distance, "mdf_view_cells": self.texture.view_cells}
        return named if self.ambient is None else {**named, "ambient_images": self.ambient}

    def release(self) -> None:
        self.texture.release()
        if self.ambient is not None:
            self.ambient.release()


def mdf_shading(ctx: moderngl.Context, material, btf, *, view_method: str, light_method: str,
                ambient: float, tile_mm: float) -> MdfShading:  # fmt: skip
    """The MDF of ``material`` for a renderer's surface program; the ambient term of
    ``btf`` (the BTF it draws, or None) when ``ambient`` > 0."""
    if material.mdf is None:
        raise RenderError(
            f"material {str(material.source)!r} holds no mdf; render it without the MDF "
            "(mdf=False, rig view --no-mdf) or run the mdf stage first"
        )
    texture = upload_mdf(ctx, mdf_table(material.mdf), view_method=view_method)
    uniforms = {
        "mdf_scale": tile_mm / material.sample_mm,
        "mdf_depth": texture.table.depth_mm,
        "max_slant": 1.0 / np.cos(np.deg2rad(GRAZING_DEG)),
    }
    if btf is None or ambient <= 0:
        return MdfShading(texture, None, uniforms)
    table = upload_ambient(ctx, btf, light_method=light_method)
    return MdfShading(texture, table, {**uniforms, "ambient": float(ambient)})
