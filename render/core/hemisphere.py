"""Quadrature of the hemisphere above a surface point, in its tangent frame.

The hemicube's texel directions and exact solid angles, and the measured lights
each direction blends as the point-light path blends them (``rig.geometry``):
the visibility maps of environment lighting (``render.environment.visibility``)
and the ambient term of the MDF's shadows (``render.points.ambient``) integrate
over the same texels.
"""

from __future__ import annotations

import numpy as np

from render._errors import RenderError
from render.core.lookup import BLEND_METHODS
from rig.geometry import barycentric_weights, carry_light_cosine, nearest_directions

__all__ = ["hemicube", "light_table"]


def _rectangle_solid_angle(x0, x1, y0, y1) -> np.ndarray:
    """Exact solid angle of the rectangle [x0, x1] × [y0, y1] on the plane at distance 1."""

    def corner(x, y):
        return np.arctan(x * y / np.sqrt(1.0 + x * x + y * y))

    return corner(x1, y1) - corner(x0, y1) - corner(x1, y0) + corner(x0, y0)


def hemicube(resolution: int) -> tuple[np.ndarray, np.ndarray]:
    """Texel directions and solid angles of a hemicube in the tangent frame.

    Parameters
    ----------
    resolution : int
        n, even, ≥ 2: the top face has n × n texels, each side n × n/2.

    Returns
    -------
    directions : (T, 3) float64, unit, z > 0
        T = n² + 4 · n · n/2 = 3n²: the top face first (rows along +y, columns
        along +x), then the sides facing +x, −x, +y, −y.
    solid_angles : (T,) float64, steradians
        Exact per texel; they sum to 2π.
    """
    if not (isinstance(resolution, int) and resolution >= 2 and resolution % 2 == 0):
        raise RenderError(f"visibility resolution = {resolution!r}: need an even int ≥ 2")
    n = resolution
    edges = np.linspace(-1.0, 1.0, n + 1)
    up_edges = np.linspace(0.0, 1.0, n // 2 + 1)
    centre = (edges[:-1] + edges[1:]) / 2
    up_centre = (up_edges[:-1] + up_edges[1:]) / 2
    # Top face z = 1: (a, b) = (x, y).
    b_top, a_top = np.meshgrid(centre, centre, indexing="ij")
    top = np.stack([a_top, b_top, np.ones_like(a_top)], axis=-1).reshape(-1, 3)
    top_omega = _rectangle_solid_angle(
        edges[None, :-1], edges[None, 1:], edges[:-1, None], edges[1:, None]
    ).reshape(-1)
    # A side face at distance 1: the coordinate across it (a) and the height z.
    z_side, a_side = np.meshgrid(up_centre, centre, indexing="ij")
    side_omega = _rectangle_solid_angle(
        edges[None, :-1], edges[None, 1:], up_edges[:-1, None], up_edges[1:, None]
    ).reshape(-1)
    a, z = a_side.reshape(-1), z_side.reshape(-1)
    one = np.ones_like(a)
    sides = [np.stack(v, axis=-1) for v in (
        (one, a, z), (-one, a, z), (a, one, z), (a, -one, z),
    )]  # fmt: skip
    directions = np.vstack([top, *sides])
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    return directions, np.concatenate([top_omega, *[side_omega] * 4])


def light_table(light_vectors, directions: np.ndarray, method: str):
    """The measured lights each of ``directions`` blends and their weights, as the
    point-light path blends them (carrying the light's cosine):
    (T, k) int64 indices, (T, k) float64 weights."""
    if method not in BLEND_METHODS:
        raise RenderError(f"light_method = {method!r}: valid are {BLEND_METHODS}")
    table = np.asarray(light_vectors, np.float64)
    if method == "barycentric":
        try:
            found = barycentric_weights(table, directions)
        except ValueError as err:
            raise RenderError(f"light_method = 'barycentric': {err}; use 'nearest4'") from err
    else:
        k = 1 if method == "nearest" else min(4, len(table))
        found = nearest_directions(table, directions, k=k)
    return found.indices, carry_light_cosine(found, table, directions)
