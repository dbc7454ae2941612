"""The ``mdf`` group of a material: the mesostructure distance function (seed 001 §3).

Arrays ``distance_mm``, ``reason``, ``count``, ``view_dirs_deg`` over all
views; version 0 is the same layout without ``format``/``version``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from rig.material._btf_model import check_directions
from rig.material._errors import MaterialError
from rig.material._groups import (
    as_uint8,
    check_version,
    finite_floats,
    format_attrs,
    other_attrs,
    read_arrays,
    require_arrays,
    write_arrays,
)

__all__ = ["UNSEEN", "Mdf", "read_mdf", "write_mdf"]

VERSION = 1
#: distance of a texel that no laser location saw
UNSEEN = -1.0
_ARRAYS = ("distance_mm", "view_dirs_deg", "reason", "count")


@dataclass(frozen=True)
class Mdf:
    """The mesostructure distance function of a material, one slot per view.

    Attributes
    ----------
    distance_mm : (n_views, N, N) float32
        D_v(x, y) in mm on the texel grid ``rig.geometry.texel_centers_mm``;
        −1 where never seen.
    view_dirs_deg : (n_views, 2) float32
        (θ, φ) of each view slot, sample frame, degrees.
    reason : (n_views, N, N) uint8
        ``processing.mdf.Reason`` per texel.
    count : (n_views, N, N) uint8
        Laser locations that contributed.
    attrs : dict
        The group's other attributes (peak detector, view names…).
    """

    distance_mm: np.ndarray
    view_dirs_deg: np.ndarray
    reason: np.ndarray
    count: np.ndarray
    attrs: dict[str, Any] = field(default_factory=dict)

    @property
    def size(self) -> int:
        return self.distance_mm.shape[1]

    def coverage(self) -> np.ndarray:
        """(n_views,) float64: fraction of texels with a value, per view."""
        return (self.distance_mm >= 0).mean(axis=(1, 2))


def write_mdf(group, mdf: Mdf) -> None:
    """Write ``mdf`` into the empty zarr ``group`` (the material's ``mdf``)."""
    arrays = _checked({name: getattr(mdf, name) for name in _ARRAYS}, where="mdf")
    write_arrays(group, arrays)
    group.attrs.update(
        {**mdf.attrs, **format_attrs("mdf", VERSION), "size": mdf.size, "unseen": UNSEEN}
    )


def read_mdf(group, *, where: str = "material/mdf") -> Mdf:
    """The ``mdf`` group (version 0 or 1)."""
    attrs = dict(group.attrs)
    check_version(attrs, "mdf", (0, VERSION), where=where)
    arrays = _checked(read_arrays(group, where=where), where=where)
    return Mdf(**arrays, attrs=other_attrs(attrs, "size", "unseen"))


def _checked(arrays: dict[str, Any], *, where: str) -> dict[str, np.ndarray]:
    require_arrays(arrays, _ARRAYS, where=where)
    distance = finite_floats("distance_mm", arrays["distance_mm"], where=where).astype(np.float32)
    if distance.ndim != 3 or distance.shape[1] != distance.shape[2] or len(distance) == 0:
        raise MaterialError(
            f"{where}: distance_mm has shape {distance.shape}, expected (n_views, N, N)"
        )
    if not np.all(np.isfinite(distance)) or np.any((distance < 0) & (distance != UNSEEN)):
        raise MaterialError(f"{where}: distance_mm must be finite, ≥ 0, or {UNSEEN} (unseen)")
    n_views = len(distance)
    views = check_directions(f"{where}: view_dirs_deg", arrays["view_dirs_deg"], n_views)
    out = {"distance_mm": distance, "view_dirs_deg": views.astype(np.float32)}
    for name in ("reason", "count"):
        value = np.asarray(arrays[name])
        if value.shape != distance.shape:
            raise MaterialError(
                f"{where}: {name} has shape {value.shape}, expected {distance.shape}"
            )
        out[name] = as_uint8(name, value, where=where)
    return out
