"""The ambient term L_a(x, y, v): the BTF integrated over every light direction.

Seed 001 §4.2 shades a point in shadow with

    L_a(x, y, v) = ∫_Ω T(x, y, v, l) dω_l

over the upper hemisphere Ω. A normtexture holds what the camera saw under
one lamp, the lamp's cosine included (the point-light path multiplies it by
the light's intensity alone), so the cosine weighting of the incoming light
is already inside T and the integral weighs directions by solid angle only:
L_a is the radiance the surface sends towards v under a uniform sky of unit
radiance (a white Lambertian texel of albedo ρ gives L_a = ρ).

Between the measured lights the integrand is the renderer's own light
interpolation (``light_method``), so L_a is what the point-light path would
show under a dense hemicube of directional lights (``render.core.hemisphere``'s
texel directions and exact solid angles). By linearity that collapses to one
weight per measured light,

    L_a = Σ_i w_i T(x, y, v, l_i),    w_i = Σ_α Δω_α h_αi,    Σ_i w_i cos θ_i = π,

(h carrying the light's cosine, ``rig.geometry.carry_light_cosine``: a Lambertian
texel's cos θ_i blends to cos θ_α, whose integral is π)

and, per view slot, to one image: made once at load time
(:func:`ambient_term`) and read by the shader with the view blend of the BTF.
"""

from __future__ import annotations

import moderngl
import numpy as np

from render._errors import RenderError
from render.core.hemisphere import hemicube, light_table
from render.core.textures import material_sampling
from rig.material import CompressedBTF, GlobalSVD

__all__ = ["ambient_term", "light_solid_angles", "upload_ambient"]

#: hemicube n of the quadrature: 3n² directions, their light weights found once per material
_RESOLUTION = 64


def light_solid_angles(
    light_vectors, *, light_method: str = "nearest4", resolution: int = _RESOLUTION
) -> np.ndarray:
    """The hemisphere's solid angle each measured light stands for.

    Parameters
    ----------
    light_vectors : (n, 3) array
        The measured light directions, sample frame.
    light_method : {"nearest4", "barycentric", "nearest"}
        How the renderer blends measured lights between them.
    resolution : int
        Hemicube n (even) of the quadrature.

    Returns
    -------
    (n,) float64, steradians
        w_i = Σ_α Δω_α h_αi over the hemicube texels α (h carrying the light's
        cosine); Σ_i w_i cos θ_i is the hemicube's ∫ cos θ dω = π.
    """
    directions, solid_angles = hemicube(resolution)
    indices, weights = light_table(light_vectors, directions, light_method)
    n = len(np.atleast_2d(light_vectors))
    return np.bincount(indices.ravel(), (weights * solid_angles[:, None]).ravel(), minlength=n)


def ambient_term(
    btf: CompressedBTF | GlobalSVD,
    *,
    light_method: str = "nearest4",
    resolution: int = _RESOLUTION,
) -> np.ndarray:
    """L_a of every view slot (seed 001 §4.2), the numpy reference the renderer uploads.

    Parameters
    ----------
    btf : CompressedBTF or GlobalSVD
    light_method, resolution :
        As in :func:`light_solid_angles`.

    Returns
    -------
    (n_views, N, N, C) float32
        Σ_i w_i T(x, y, v_j, l_i) per view slot j, in the BTF's units times
        steradians; finite wherever the BTF is.
    """
    if not isinstance(btf, CompressedBTF | GlobalSVD):
        raise RenderError(
            f"ambient term: expected a CompressedBTF or GlobalSVD, got {type(btf).__name__}"
        )
    w = light_solid_angles(btf.light_vectors, light_method=light_method, resolution=resolution)
    lights = np.arange(len(w))
    return np.stack([btf.blend([j], [1.0], lights, w) for j in range(len(btf.view_dirs_deg))])


def upload_ambient(ctx: moderngl.Context, btf, *, light_method: str) -> moderngl.TextureArray:
    """:func:`ambient_term` as a float32 texture array, a layer per view slot (rows
    flipped, repeating, mipmapped like the BTF's images; grey read as grey RGB)."""
    ambient = ambient_term(btf, light_method=light_method)
    n_views, n, _, channels = ambient.shape
    data = np.ascontiguousarray(ambient[:, ::-1], np.float32)
    return material_sampling(
        ctx.texture_array((n, n, n_views), channels, data, dtype="f4"), channels
    )
