"""Textures at measured and unmeasured directions (seed 000 §4.2).

A light direction between the measured ones blends the textures of nearby
measured lights: the 4 nearest with Shepard weights (``"nearest4"``, as the
seed), the 3 corners of the spherical triangle holding it (``"barycentric"``),
or just the nearest (``"nearest"``, the baseline). A light's weights carry the
irradiance's cosine (``rig.geometry.carry_light_cosine``): a texture holds
cos θ_i of its light, so each is scaled by cos θ_query / cos θ_i. A view
direction blends the view slots the same way, without the cosine (seed 000
eq. (5)). All are exact at measured directions: a query on a table direction
gets weight 1 there.
"""

from __future__ import annotations

from typing import Literal

import numpy as np

from processing.btf._errors import BtfError
from rig.geometry import (
    Interpolation,
    barycentric_weights,
    carry_light_cosine,
    direction_vector,
    nearest_directions,
)
from rig.material import CompressedBTF, GlobalSVD

__all__ = ["Method", "direction_weights", "interpolate", "light_weights", "reconstruct"]

Method = Literal["nearest", "nearest4", "barycentric"]
_METHODS = ("nearest", "nearest4", "barycentric")


def direction_weights(table_vectors, query_deg, *, method: Method) -> tuple[np.ndarray, np.ndarray]:
    """Indices (k,) and weights (k,) of the table directions blended for one query.

    Parameters
    ----------
    table_vectors : (n, 3) array
        Measured directions.
    query_deg : (2,) array
        (θ, φ) of the wanted direction, degrees.
    method : {"nearest", "nearest4", "barycentric"}
    """
    found = _blend(table_vectors, query_deg, method)
    return found.indices[0], found.weights[0]


def light_weights(table_vectors, query_deg, *, method: Method) -> tuple[np.ndarray, np.ndarray]:
    """:func:`direction_weights` of a light: each weight times cos θ_query / cos θ_i
    (``rig.geometry.carry_light_cosine``; they no longer sum to 1)."""
    found = _blend(table_vectors, query_deg, method)
    query = direction_vector(*np.asarray(query_deg, np.float64))[None, :]
    return found.indices[0], carry_light_cosine(found, table_vectors, query)[0]


def _blend(table_vectors, query_deg, method: Method) -> Interpolation:
    q = np.asarray(query_deg, dtype=np.float64)
    if q.shape != (2,) or not np.all(np.isfinite(q)) or not 0 <= q[0] <= 90:
        raise BtfError(f"direction {query_deg}: expected finite (theta_deg, phi_deg), θ in [0, 90]")
    table = np.asarray(table_vectors, dtype=np.float64)
    query = direction_vector(q[0], q[1])[None, :]
    if method == "nearest":
        return nearest_directions(table, query, k=1)
    if method == "nearest4":
        return nearest_directions(table, query, k=min(4, len(table)))
    if method == "barycentric":
        try:
            return barycentric_weights(table, query)
        except ValueError as err:
            raise BtfError(
                "barycentric interpolation needs ≥ 3 measured directions spanning the "
                "hemisphere; use method='nearest4'"
            ) from err
    raise BtfError(f"method = {method!r}: valid are {_METHODS}")


def reconstruct(model: CompressedBTF | GlobalSVD, *, view: int, light: int) -> np.ndarray:
    """The compressed normtexture of measured view slot ``view`` and light ``light``.

    Returns
    -------
    (N, N, C) float32
    """
    n_views, n_lights = len(model.view_dirs_deg), len(model.light_dirs_deg)
    if not (0 <= view < n_views and 0 <= light < n_lights):
        raise BtfError(
            f"(view, light) = ({view}, {light}): valid are 0 ≤ view < {n_views}, "
            f"0 ≤ light < {n_lights}"
        )
    return model.blend([view], [1.0], [light], [1.0])


def interpolate(
    model: CompressedBTF | GlobalSVD,
    *,
    view_deg,
    light_deg,
    light_method: Method = "nearest4",
    view_method: Method = "nearest4",
) -> np.ndarray:
    """The texture for any view and light direction (sample frame, degrees).

    Returns
    -------
    (N, N, C) float32
        Exactly :func:`reconstruct` when both directions were measured.
    """
    light_idx, light_w = light_weights(model.light_vectors, light_deg, method=light_method)
    view_idx, view_w = direction_weights(model.view_vectors, view_deg, method=view_method)
    return model.blend(view_idx, view_w, light_idx, light_w)
