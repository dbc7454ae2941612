"""The glTF PBR model of the ``pbr`` group, on the CPU: metallic-roughness core (metallic
0), KHR_materials_specular, KHR_materials_sheen and KHR_materials_anisotropy.

One evaluation for the fit (``processing.pbr``), the renderer's ``pbr`` layer and the
web viewer (whose shaders port it line by line), and the tests. The
formulas are the glTF 2.0 specification's Appendix B and the extensions' own:

- specular lobe (anisotropy): α = roughness², α_t = mix(α, 1, s²), α_b = α;
  D = α_t α_b w² / π with w = α_t α_b / |(α_b T·H, α_t B·H, α_t α_b N·H)|²;
  V = 0.5 / (N·L |(α_t T·V, α_b B·V, N·V)| + N·V |(α_t T·L, α_b B·L, N·L)|);
- dielectric Fresnel mix: f0 = min(0.04 · specular_colour, 1) · specular, f90 = specular,
  F = f0 + (f90 − f0)(1 − V·H)⁵, base = (1 − F) · base_colour / π + F · D · V;
- sheen: Charlie D = (2 + 1/r) sin(θ_h)^(1/r) / 2π and its visibility
  (1 + Λ(N·V) + Λ(N·L))⁻¹ / (4 N·V N·L), r = sheen roughness (at least 0.07, as the
  sample viewer clamps it), layered by albedo scaling:
  f = f_sheen + base · min(1 − max(sheen_colour) E(N·V), 1 − max(sheen_colour) E(N·L)),
  E the sheen's directional albedo (:func:`sheen_albedo`, a table integrated here).

Values are what a BTF measures: radiance relative to a white diffuse target lit
frontally, i.e. π f(l, v) max(N·L, 0) (1 for base colour 1 at normal incidence without
specular). Directions are unit vectors in the sample frame (z the sample normal).
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from functools import cache

import numpy as np

__all__ = [
    "SHEEN_ROUGHNESS_MIN",
    "PbrParams",
    "anisotropy_frame",
    "evaluate",
    "evaluate_terms",
    "sheen_albedo",
]

#: the sheen roughness below which the Charlie lobe is clamped (glTF sample viewer)
SHEEN_ROUGHNESS_MIN = 0.07
_DIELECTRIC_F0 = 0.04  # ((ior − 1) / (ior + 1))² for glTF's ior 1.5
_EPS = 1e-7


@dataclass(frozen=True)
class PbrParams:
    """Per-texel glTF material parameters; every field has the same leading shape (...).

    Attributes
    ----------
    base_colour : (..., C) linear, [0, 1]
    roughness : (...,) perceptual roughness, [0, 1] (α = roughness²)
    specular : (...,) KHR_materials_specular ``specularFactor``, [0, 1]
    specular_colour : (...,) grey ``specularColorFactor`` (f0 = min(0.04 ×, 1) × specular), ≥ 0
    sheen_colour : (..., C) linear, [0, 1]
    sheen_roughness : (...,) [0, 1]
    anisotropy : (...,) KHR_materials_anisotropy strength, [0, 1]
    anisotropy_deg : (...,) direction of the stretched lobe in the tangent plane, degrees
        from the tangent (+x of the sample frame) towards the bitangent (+y)
    normal : (..., 3) unit, sample frame (= tangent frame of the flat sample)
    """

    base_colour: np.ndarray
    roughness: np.ndarray
    specular: np.ndarray
    specular_colour: np.ndarray
    sheen_colour: np.ndarray
    sheen_roughness: np.ndarray
    anisotropy: np.ndarray
    anisotropy_deg: np.ndarray
    normal: np.ndarray

    def map(self, function) -> PbrParams:
        """A PbrParams with ``function`` applied to every field (indexing, reshaping…)."""
        return PbrParams(**{f.name: function(getattr(self, f.name)) for f in fields(self)})


def anisotropy_frame(anisotropy_deg: np.ndarray):
    """Tangent T (along the stretched lobe) and bitangent B of each texel, (..., 3) float64.

    As glTF viewers build them: the direction turns the mesh's tangent in the
    geometric tangent plane, T = (cos φ, sin φ, 0), and B = N_geometric × T — the flat
    sample's +z, not the normal map's normal.
    """
    phi = np.deg2rad(np.asarray(anisotropy_deg, np.float64))
    zero = np.zeros_like(phi)
    t = np.stack([np.cos(phi), np.sin(phi), zero], axis=-1)
    b = np.stack([-np.sin(phi), np.cos(phi), zero], axis=-1)
    return t, b


def evaluate(params: PbrParams, light: np.ndarray, view: np.ndarray) -> np.ndarray:
    """Relative radiance π f(l, v) max(N·L, 0) of each texel for each direction pair.

    Parameters
    ----------
    params : PbrParams with leading shape (T,)
    light, view : (M, 3) unit vectors, sample frame, pointing away from the surface; or
        (T, M, 3), each texel's own

    Returns
    -------
    (T, M, C) float64; 0 where the light or the view is below the texel's tangent plane.
    """
    diffuse, specular, sheen = evaluate_terms(params, light, view)
    base = np.asarray(params.base_colour, np.float64)[:, None]
    return (
        diffuse[..., None] * base
        + specular[..., None]
        + sheen[..., None] * np.asarray(params.sheen_colour, np.float64)[:, None]
    )


def evaluate_terms(params: PbrParams, light: np.ndarray, view: np.ndarray):
    """The three terms of :func:`evaluate`: radiance = diffuse · base_colour + specular +
    sheen · sheen_colour, each (T, M) float64 (all hold the sheen's albedo scaling, so they
    depend on max(sheen_colour); the colours enter only where shown).
    """
    p = params.map(lambda a: np.asarray(a, np.float64)[:, None])  # (T, 1, ...)
    lx, ly, lz = _per_texel(light)
    vx, vy, vz = _per_texel(view)
    nx, ny, nz = (p.normal[..., k] for k in range(3))
    t, b = anisotropy_frame(p.anisotropy_deg)
    hx, hy, hz = lx + vx, ly + vy, lz + vz
    inverse = 1.0 / np.maximum(np.sqrt(hx * hx + hy * hy + hz * hz), _EPS)
    hx, hy, hz = hx * inverse, hy * inverse, hz * inverse

    def dot(u, x, y, z):
        return u[..., 0] * x + u[..., 1] * y + u[..., 2] * z

    n_l, n_v = nx * lx + ny * ly + nz * lz, nx * vx + ny * vy + nz * vz
    lit = (n_l > 0) & (n_v > 0)
    n_l, n_v = np.clip(n_l, _EPS, 1.0), np.clip(n_v, _EPS, 1.0)
    n_h = np.clip(nx * hx + ny * hy + nz * hz, 0.0, 1.0)
    v_h = np.clip(vx * hx + vy * hy + vz * hz, 0.0, 1.0)

    alpha = np.maximum(p.roughness**2, 1e-4)
    alpha_t = alpha + (1.0 - alpha) * p.anisotropy**2
    alpha_b = alpha
    a2 = alpha_t * alpha_b
    fx, fy, fz = alpha_b * dot(t, hx, hy, hz), alpha_t * dot(b, hx, hy, hz), a2 * n_h
    w2 = a2 / np.maximum(fx * fx + fy * fy + fz * fz, 1e-30)
    distribution = a2 * w2 * w2 / np.pi
    t_v, b_v = alpha_t * dot(t, vx, vy, vz), alpha_b * dot(b, vx, vy, vz)
    t_l, b_l = alpha_t * dot(t, lx, ly, lz), alpha_b * dot(b, lx, ly, lz)
    vis_v = n_l * np.sqrt(t_v * t_v + b_v * b_v + n_v * n_v)
    vis_l = n_v * np.sqrt(t_l * t_l + b_l * b_l + n_l * n_l)
    visibility = 0.5 / np.maximum(vis_v + vis_l, _EPS)

    f0 = np.minimum(_DIELECTRIC_F0 * p.specular_colour, 1.0) * p.specular
    fresnel = f0 + (p.specular - f0) * (1.0 - v_h) ** 5
    r = np.clip(p.sheen_roughness, SHEEN_ROUGHNESS_MIN, 1.0)
    peak = np.max(p.sheen_colour, axis=-1)
    scaling = np.minimum(1.0 - peak * sheen_albedo(n_v, r), 1.0 - peak * sheen_albedo(n_l, r))
    # π f N·L with f = f_sheen + scaling · ((1 − F) base / π + F D V)
    cosine = np.where(lit, n_l, 0.0)
    diffuse = scaling * (1.0 - fresnel) * cosine
    specular = np.pi * scaling * fresnel * distribution * visibility * cosine
    return diffuse, specular, np.pi * _charlie(r, n_h, n_l, n_v) * cosine


def _per_texel(directions) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """x, y, z of (M, 3) directions shared by every texel, as (1, M), or of (T, M, 3)."""
    d = np.asarray(directions, np.float64)
    d = d[None] if d.ndim == 2 else d
    return d[..., 0], d[..., 1], d[..., 2]


def _charlie(r, n_h, n_l, n_v):
    """The Charlie sheen lobe D·V for roughness ``r`` (broadcast), without colour."""
    sin2 = np.maximum(1.0 - n_h * n_h, 0.0)
    distribution = (2.0 + 1.0 / r) * sin2 ** (0.5 / r) / (2.0 * np.pi)
    denominator = (1.0 + _lambda_sheen(n_v, r) + _lambda_sheen(n_l, r)) * 4.0 * n_v * n_l
    return distribution / np.maximum(denominator, _EPS)


def _lambda_sheen(cos_theta, r):
    def ell(x, r):
        t = (1.0 - r) ** 2
        a = 21.5473 + (25.3245 - 21.5473) * t
        b = 3.82987 + (3.32435 - 3.82987) * t
        c = 0.19823 + (0.16801 - 0.19823) * t
        d = -1.97760 + (-1.27393 + 1.97760) * t
        e = -4.32054 + (-4.85967 + 4.32054) * t
        return a / (1.0 + b * np.maximum(x, 0.0) ** c) + d * x + e

    x = np.abs(cos_theta)
    return np.where(x < 0.5, np.exp(ell(x, r)), np.exp(2.0 * ell(0.5, r) - ell(1.0 - x, r)))


@cache
def _sheen_table(n_cos: int = 33, n_rough: int = 25, n_quad: int = 64):
    """E(cosθ, r) on a grid: ∫ D·V (N·L) dω_L by midpoint quadrature over the hemisphere."""
    cos_grid = np.linspace(0.0, 1.0, n_cos)
    rough_grid = np.linspace(SHEEN_ROUGHNESS_MIN, 1.0, n_rough)
    u = (np.arange(n_quad) + 0.5) / n_quad  # cosθ_l uniform: dω = dcosθ dφ
    phi = np.pi * (np.arange(n_quad) + 0.5) / n_quad  # symmetric in φ: half the circle, × 2
    cos_l, phi_l = np.meshgrid(u, phi, indexing="ij")
    sin_l = np.sqrt(1.0 - cos_l**2)
    light = np.stack([sin_l * np.cos(phi_l), sin_l * np.sin(phi_l), cos_l], -1).reshape(-1, 3)
    table = np.zeros((n_cos, n_rough))
    for i, mu in enumerate(np.maximum(cos_grid, 1e-3)):
        view = np.array([np.sqrt(1.0 - mu * mu), 0.0, mu])
        half = light + view
        half /= np.linalg.norm(half, axis=-1, keepdims=True)
        for j, r in enumerate(rough_grid):
            lobe = _charlie(r, half[:, 2], light[:, 2], mu)
            table[i, j] = 2.0 * np.sum(lobe * light[:, 2]) * (1.0 / n_quad) * (np.pi / n_quad)
    return cos_grid, rough_grid, table


def sheen_albedo(cos_theta, sheen_roughness) -> np.ndarray:
    """The sheen layer's directional albedo E for colour 1 (bilinear in the integrated table).

    ``cos_theta`` and ``sheen_roughness`` broadcast; returns float64 in [0, 1].
    """
    cos_grid, rough_grid, table = _sheen_table()
    x = np.clip(np.asarray(cos_theta, np.float64), 0.0, 1.0) * (len(cos_grid) - 1)
    r = np.clip(np.asarray(sheen_roughness, np.float64), rough_grid[0], 1.0)
    y = (r - rough_grid[0]) / (rough_grid[-1] - rough_grid[0]) * (len(rough_grid) - 1)
    x0 = np.clip(np.floor(x).astype(int), 0, len(cos_grid) - 2)
    y0 = np.clip(np.floor(y).astype(int), 0, len(rough_grid) - 2)
    fx, fy = x - x0, y - y0
    top = table[x0, y0] * (1 - fy) + table[x0, y0 + 1] * fy
    bottom = table[x0 + 1, y0] * (1 - fy) + table[x0 + 1, y0 + 1] * fy
    return np.clip(top * (1 - fx) + bottom * fx, 0.0, 1.0)
