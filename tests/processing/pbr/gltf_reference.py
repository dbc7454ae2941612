"""The glTF BRDF written out again from the specification's formulas, for the tests.

Independent of ``processing.pbr``: per direction pair in plain numpy, the sheen's directional
albedo E integrated by Gauss–Legendre quadrature rather than looked up. Sources:
glTF 2.0 Appendix B; KHR_materials_specular, KHR_materials_sheen (Charlie distribution
and visibility, albedo scaling with min over N·V and N·L), KHR_materials_anisotropy.
"""

from __future__ import annotations

import numpy as np

SHEEN_MIN = 0.07  # the clamp of the glTF sample viewer


def _lambda(cos, r):
    t = (1 - r) ** 2
    coef = [(21.5473, 25.3245), (3.82987, 3.32435), (0.19823, 0.16801),
            (-1.97760, -1.27393), (-4.32054, -4.85967)]  # fmt: skip
    a, b, c, d, e = (lo + (hi - lo) * t for lo, hi in coef)

    def ell(x):
        return a / (1 + b * x**c) + d * x + e

    cos = abs(cos)
    return np.exp(ell(cos)) if cos < 0.5 else np.exp(2 * ell(0.5) - ell(1 - cos))


def charlie(r, n_h, n_l, n_v):
    """D·V of the sheen lobe (no colour)."""
    d = (2 + 1 / r) * (1 - n_h * n_h) ** (1 / (2 * r)) / (2 * np.pi)
    return d / ((1 + _lambda(n_v, r) + _lambda(n_l, r)) * 4 * n_v * n_l)


def sheen_e(mu, r, order=40):
    """∫ charlie · cosθ_l dω for a view at cosθ = mu (Gauss–Legendre in cosθ_l and φ)."""
    x, w = np.polynomial.legendre.leggauss(order)
    cos_l, w_c = 0.5 * (x + 1), 0.5 * w
    phi, w_p = np.pi * (x + 1), np.pi * w
    total = 0.0
    view = np.array([np.sqrt(max(1 - mu * mu, 0)), 0, mu])
    for c, wc in zip(cos_l, w_c, strict=True):
        s = np.sqrt(1 - c * c)
        for p, wp in zip(phi, w_p, strict=True):
            light = np.array([s * np.cos(p), s * np.sin(p), c])
            h = (light + view) / np.linalg.norm(light + view)
            total += wc * wp * charlie(r, h[2], c, max(mu, 1e-4)) * c
    return total


def radiance(m: dict, light, view, *, e_table=None) -> np.ndarray:
    """π f(l, v) N·L for one texel's parameters ``m`` (names as PbrParams) and one pair."""
    n = np.asarray(m["normal"], float)
    to_light, v = np.asarray(light, float), np.asarray(view, float)
    n_l, n_v = n @ to_light, n @ v
    if n_l <= 0 or n_v <= 0:
        return np.zeros(len(m["base_colour"]))
    h = (to_light + v) / np.linalg.norm(to_light + v)
    # anisotropicT = TBN (cos, sin, 0) with the mesh's frame; anisotropicB = N_geometric × T
    tbn = np.eye(3)  # the flat sample: tangent +x, bitangent +y, geometric normal +z
    phi = np.deg2rad(m["anisotropy_deg"])
    t = tbn @ np.array([np.cos(phi), np.sin(phi), 0.0])
    b = np.cross(tbn[:, 2], t)
    alpha = max(m["roughness"] ** 2, 1e-4)
    at = alpha + (1 - alpha) * m["anisotropy"] ** 2
    ab = alpha
    d = 1 / (np.pi * at * ab * ((t @ h / at) ** 2 + (b @ h / ab) ** 2 + (n @ h) ** 2) ** 2)
    lambda_v = n_l * np.linalg.norm([at * (t @ v), ab * (b @ v), n_v])
    lambda_l = n_v * np.linalg.norm([at * (t @ to_light), ab * (b @ to_light), n_l])
    vis = 0.5 / (lambda_v + lambda_l)
    f0 = min(0.04 * m["specular_colour"], 1.0) * m["specular"]
    fresnel = f0 + (m["specular"] - f0) * (1 - v @ h) ** 5
    base = (1 - fresnel) * np.asarray(m["base_colour"]) / np.pi + fresnel * d * vis
    r = min(max(m["sheen_roughness"], SHEEN_MIN), 1.0)
    sheen_colour = np.asarray(m["sheen_colour"], float)
    e = e_table or (lambda mu, r: sheen_e(mu, r))
    peak = sheen_colour.max()
    scaling = min(1 - peak * e(n_v, r), 1 - peak * e(n_l, r)) if peak > 0 else 1.0
    f = sheen_colour * charlie(r, n @ h, n_l, n_v) + base * scaling
    return np.pi * f * n_l
