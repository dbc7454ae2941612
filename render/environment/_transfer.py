"""The environment through the visibility maps into per-vertex BTF coefficients.

Seed 000 §5.3 eq. (10)–(12). For vertex v the radiance arriving from measured
light direction i is g_i = Σ_α V_α L(ω_α) Δω_α h_αi over its hemicube texels α
(visibility V, environment radiance L in the texel's scene direction averaged
over the texel's width (:meth:`EnvironmentMap.mean_lookup`), the texel's solid
angle Δω and its light weights h). A normtexture holds what the
camera saw under one lamp, the lamp's cosine included (the point-light path
multiplies it by the light's intensity alone), so a texel weighs by its solid
angle only. Per view slot j the texture under the environment is then

    T_j = Σ_i g_i N_ij = (Σ_i g_i) m_j + Σ_k γ*_kj B_kj,   γ*_kj = Σ_i g_i p_ikj,

and U holds, for every vertex and slot, the RGB coefficient of the mean
followed by the c coefficients γ*_kj: ``(V, n_views, c + 1, 3)``. A global
SVD's eigenmaps E_k(x, l) depend on the light (seed 001 §5), so no γ* per slot
exists: T = Σ_i g_i Σ_k ω_k E_k(x, l_i) with the view weights ω, and U is g
itself, ``(V, n_lights, 1, 3)``; the fragment sums over the measured lights.
U is made once per environment (or rotation of it); the exposure f only
scales the frame (eq. (11)).
"""

from __future__ import annotations

import numpy as np

from render._errors import RenderError
from rig.material import CompressedBTF, GlobalSVD

__all__ = ["check_btf", "environment_coefficients", "light_radiance", "texture_at_vertex"]

# Work per pass, whatever the vertex count: texel rows gathered at once (each 3
# float64 several times over, ~100 MB) and vertices whose g and γ* are held (8192
# vertices × 81 lights or 27 slots × 8 components × 3 float64: tens of MB).
_TEXELS_PER_PASS = 1 << 21
_VERTICES_PER_PASS = 1 << 13


def check_btf(btf) -> CompressedBTF | GlobalSVD:
    if not isinstance(btf, CompressedBTF | GlobalSVD):
        held = type(btf).__name__ if btf is not None else "no BTF"
        raise RenderError(
            "environment lighting through visibility maps needs a compressed BTF (per-view PCA "
            f"or global SVD); the material holds {held}: light it by partial environment maps "
            "(render.PemRenderer)"
        )
    return btf


def light_radiance(maps, environment, n_lights: int, vertices=slice(None)) -> np.ndarray:
    """g: (V', n_lights, 3) float64, radiance arriving from each measured light direction.

    The environment's rotation applies; its exposure does not.
    """
    blend = np.zeros((maps.texels, n_lights))
    np.add.at(blend, (np.arange(maps.texels)[:, None], maps.light_indices), maps.light_weights)
    frames = maps.frames[vertices].astype(np.float64)
    visible = maps.visibility(vertices)
    out = np.empty((len(frames), n_lights, 3))
    per_pass = max(1, _TEXELS_PER_PASS // maps.texels)
    # Each texel reads the map averaged over its own width: a sun smaller than a texel
    # lights every vertex that sees it with its own light, not 0 or several times it.
    texel_width = np.sqrt(maps.solid_angles)
    for first in range(0, len(frames), per_pass):
        part = slice(first, first + per_pass)
        scene_dirs = maps.directions @ frames[part]  # (v, T, 3)
        radiance = environment.mean_lookup(scene_dirs, texel_width)
        radiance *= (visible[part] * maps.solid_angles)[..., None]
        out[part] = np.swapaxes(np.tensordot(radiance, blend, axes=([1], [0])), 1, 2)
    return out


def environment_coefficients(maps, environment, btf) -> np.ndarray:
    """U: (V, n_views, c + 1, 3) float32 per-vertex coefficients (see the module).

    ``maps`` must have been built on ``btf``'s light directions.
    """
    btf = check_btf(btf)
    lights = len(btf.light_dirs_deg)
    if int(maps.light_indices.max()) >= lights:
        raise RenderError(
            f"visibility maps blend light {int(maps.light_indices.max())} but the material "
            f"measured {lights}: build them on the material's light directions"
        )
    vertices = len(maps.frames)
    if isinstance(btf, GlobalSVD):
        out = np.empty((vertices, lights, 1, 3), np.float32)
        per_pass = max(1, min(_TEXELS_PER_PASS // maps.texels, _VERTICES_PER_PASS))
        for first in range(0, vertices, per_pass):
            part = slice(first, first + per_pass)
            out[part, :, 0] = light_radiance(maps, environment, lights, part)
        return out
    n_views, c = len(btf.view_dirs_deg), btf.components
    weights = np.asarray(btf.weights, np.float64)  # (n_views, n_lights, c)
    out = np.empty((vertices, n_views, c + 1, 3), np.float32)
    per_pass = max(1, min(_TEXELS_PER_PASS // maps.texels, _VERTICES_PER_PASS))
    for first in range(0, vertices, per_pass):
        part = slice(first, first + per_pass)
        g = light_radiance(maps, environment, lights, part)
        out[part, :, 0] = g.sum(axis=1)[:, None, :]
        gamma = np.tensordot(g, weights, axes=([1], [1]))  # (v, 3, n_views, c)
        out[part, :, 1:] = np.transpose(gamma, (0, 2, 3, 1))
    return out


def texture_at_vertex(btf, coefficients, view_idx, view_w) -> np.ndarray:
    """(N, N, 3) float64 texture of one vertex under the environment, exposure 1.

    ``coefficients`` (n_views, c + 1, 3) — a global SVD's (n_lights, 1, 3) — is one
    vertex's rows of U; the view slots ``view_idx`` are blended with ``view_w``
    (seed 000 eq. (5)).
    """
    if isinstance(btf, GlobalSVD):
        out = 0.0
        for light, g in enumerate(np.asarray(coefficients, np.float64)[:, 0]):
            if g.any():
                out = out + g * btf.blend(view_idx, view_w, [light], [1.0]).astype(np.float64)
        return np.asarray(out)
    out = 0.0
    for slot, w in zip(np.asarray(view_idx), np.asarray(view_w, np.float64), strict=True):
        if w == 0.0:
            continue
        coef = coefficients[slot].astype(np.float64)
        texture = coef[0] * btf.mean[slot].astype(np.float64)
        basis = btf.basis[slot].astype(np.float64)  # (c, N, N, C), C = 1 or 3
        texture = texture + np.sum(coef[1:, None, None, :] * basis, axis=0)
        out = out + w * texture
    return np.asarray(out)
