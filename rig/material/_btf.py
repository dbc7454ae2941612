"""The ``btf`` group of a material: a compressed BTF (``docs/material.md``).

:func:`btf_to_arrays` gives the arrays and JSON-able attributes of the group,
:func:`btf_from_arrays` rebuilds the model; :func:`write_btf` and
:func:`read_btf` put them into and take them from a zarr group, with the
per-slot ``slot_valid`` flags and the ``radiometry`` record (version 2; version 1
groups have none and read as ``NOT_RECORDED``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from rig.material._btf_model import CompressedBTF, GlobalSVD, check_directions
from rig.material._errors import MaterialError
from rig.material._groups import (
    check_version,
    finite_floats,
    format_attrs,
    other_attrs,
    read_arrays,
    write_arrays,
)
from rig.material._radiometry import NOT_RECORDED, Radiometry

__all__ = ["BtfGroup", "btf_from_arrays", "btf_to_arrays", "read_btf", "write_btf"]

VERSION = 2
#: versions read: 1 lacks ``radiometry``
_READABLE = (1, VERSION)
_TEXTURE = np.float16


def _texture(name: str, values: np.ndarray) -> np.ndarray:
    v = np.asarray(values)
    limit = float(np.finfo(_TEXTURE).max)
    peak = float(np.abs(v).max(initial=0.0))
    if not np.isfinite(peak) or peak > limit:
        raise MaterialError(
            f"btf {name} reaches {peak:.4g}, beyond float16 (max {limit:.4g}); scale the BTF "
            "(e.g. to radiance in [0, 1]) before compressing"
        )
    return v.astype(_TEXTURE)


def btf_to_arrays(
    model: CompressedBTF | GlobalSVD, *, units: str = "relative radiance"
) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """Arrays and attributes of the material's ``btf`` group.

    Parameters
    ----------
    model : CompressedBTF or GlobalSVD
    units : str
        What the texture values measure (stored as an attribute).

    Returns
    -------
    arrays : dict[str, ndarray]
        ``view_dirs_deg`` (n_views, 2) float32, ``light_dirs_deg`` (n_lights, 2)
        float32, and for ``kind = "pca"``: ``mean`` (n_views, N, N, C) float16,
        ``basis`` (n_views, c, N, N, C) float16, ``weights`` (n_views,
        n_lights, c) float32, ``rank`` (n_views,) int32; for ``kind = "svd"``:
        ``eigenmaps`` (c, n_lights, N, N, C) float16, ``weights`` (n_views, c)
        float32.
    attrs : dict
        ``format``, ``version``, ``kind``, ``components``, ``size``,
        ``channels``, ``units``, ``angles`` ("degrees, sample frame, θ from +z,
        φ from +x towards +y").
    """
    arrays: dict[str, np.ndarray] = {
        "view_dirs_deg": model.view_dirs_deg.astype(np.float32),
        "light_dirs_deg": model.light_dirs_deg.astype(np.float32),
    }
    if isinstance(model, CompressedBTF):
        kind = "pca"
        channels = model.mean.shape[-1]
        arrays["mean"] = _texture("mean", model.mean)
        arrays["basis"] = _texture("basis", model.basis)
        arrays["weights"] = model.weights.astype(np.float32)
        arrays["singular_values"] = model.singular_values.astype(np.float32)
        arrays["rank"] = model.rank.astype(np.int32)
    elif isinstance(model, GlobalSVD):
        kind = "svd"
        channels = model.eigenmaps.shape[-1]
        arrays["eigenmaps"] = _texture("eigenmaps", model.eigenmaps)
        arrays["weights"] = model.weights.astype(np.float32)
        arrays["singular_values"] = model.singular_values.astype(np.float32)
    else:
        raise MaterialError(
            f"btf model: expected CompressedBTF or GlobalSVD, got {type(model).__name__}"
        )
    attrs = {
        **format_attrs("btf", VERSION),
        "kind": kind,
        "components": int(model.components),
        "size": int(model.size),
        "channels": int(channels),
        "units": str(units),
        "angles": "degrees, sample frame, theta from +z, phi from +x towards +y",
        "rank": int(model.rank) if kind == "svd" else None,
    }
    return arrays, attrs


def btf_from_arrays(
    arrays: dict[str, np.ndarray], attrs: dict[str, Any], *, where: str = "material btf"
) -> CompressedBTF | GlobalSVD:
    """Rebuild the model written by :func:`btf_to_arrays` (float16 textures stay float16).

    MaterialError naming ``where`` and the attribute or array at fault for a
    group that is not a btf group of version 1 or 2, or whose arrays do not fit
    (a shape, a dtype, a NaN or inf value).
    """
    check_version(attrs, "btf", _READABLE, where=where)
    kind = attrs.get("kind")
    needed = {
        "pca": ("mean", "basis", "weights", "singular_values", "rank"),
        "svd": ("eigenmaps", "weights", "singular_values"),
    }.get(kind)
    if needed is None:
        raise MaterialError(f"{where}: attribute kind = {kind!r}; valid are 'pca' and 'svd'")
    missing = [k for k in ("view_dirs_deg", "light_dirs_deg", *needed) if k not in arrays]
    if missing:
        raise MaterialError(f"{where} ({kind}) lacks arrays {missing}")
    views = check_directions(f"{where}: view_dirs_deg", arrays["view_dirs_deg"])
    lights = check_directions(f"{where}: light_dirs_deg", arrays["light_dirs_deg"])
    a = {k: finite_floats(k, arrays[k], where=where) for k in needed if k != "rank"}
    n_views, n_lights = len(views), len(lights)
    if kind == "pca":
        c = a["basis"].shape[1] if a["basis"].ndim == 5 else -1
        expected = {
            "mean": (n_views, *a["mean"].shape[1:]),
            "basis": (n_views, c, *a["mean"].shape[1:]),
            "weights": (n_views, n_lights, c),
            "singular_values": (n_views, n_lights),
            "rank": (n_views,),
        }
        a["rank"] = _ranks(arrays["rank"], c, where=where)
        for name, shape in expected.items():
            if a[name].shape != shape:
                raise MaterialError(f"{where}: {name} has shape {a[name].shape}, expected {shape}")
        return CompressedBTF(
            views, lights, a["mean"], a["basis"], a["weights"], a["singular_values"], a["rank"]
        )
    c = a["eigenmaps"].shape[0]
    if a["eigenmaps"].ndim != 5 or a["eigenmaps"].shape[1] != n_lights:
        raise MaterialError(
            f"{where}: eigenmaps has shape {a['eigenmaps'].shape}, expected "
            f"(c, {n_lights}, N, N, C)"
        )
    if a["weights"].shape != (n_views, c):
        raise MaterialError(
            f"{where}: weights has shape {a['weights'].shape}, expected {(n_views, c)}"
        )
    rank = int(attrs.get("rank") or c)
    return GlobalSVD(views, lights, a["eigenmaps"], a["weights"], a["singular_values"], rank)


def _ranks(value, components: int, *, where: str) -> np.ndarray:
    """The per-slot ranks: whole numbers in 0…``components``."""
    rank = np.asarray(value)
    whole = rank.dtype.kind in "iu"
    if not whole or (rank.size and not 0 <= rank.min() <= rank.max() <= components):
        raise MaterialError(
            f"{where}: rank ({rank.dtype}) must hold whole numbers in 0…{components} (the "
            "components of each slot's basis)"
        )
    return rank


@dataclass(frozen=True)
class BtfGroup:
    """A ``btf`` group as read: the model, which view slots hold data, and the rest.

    ``slot_valid`` (n_views,) bool: False for a slot stored empty (its frames
    could not be registered); all True when the group has no ``slot_valid``.
    ``radiometry``: the corrections applied to the frames (``NOT_RECORDED`` for
    version 1). ``attrs``: the group's other attributes (``flagged``…).
    """

    model: CompressedBTF | GlobalSVD
    slot_valid: np.ndarray
    units: str
    attrs: dict[str, Any]
    radiometry: Radiometry = NOT_RECORDED


def write_btf(
    group,
    model: CompressedBTF | GlobalSVD,
    *,
    units: str,
    slot_valid=None,
    radiometry: Radiometry = Radiometry(),
    attrs: dict[str, Any] | None = None,
) -> None:
    """Write ``model`` into the empty zarr ``group`` (the material's ``btf``).

    ``slot_valid`` (n_views,) bool marks the slots that hold data (default:
    all); ``radiometry`` records the corrections applied to the frames
    (default: none); ``attrs`` are extra JSON-able attributes (e.g. the frames
    flagged).
    """
    arrays, own = btf_to_arrays(model, units=units)
    n_views = len(arrays["view_dirs_deg"])
    valid = np.ones(n_views, bool) if slot_valid is None else np.asarray(slot_valid)
    if valid.shape != (n_views,) or valid.dtype != bool:
        raise MaterialError(
            f"btf slot_valid: shape {valid.shape} dtype {valid.dtype}, expected ({n_views},) bool"
        )
    own["radiometry"] = radiometry.to_attrs()
    clash = sorted(set(attrs or {}) & set(own))
    if clash:
        raise MaterialError(f"btf attrs {clash}: the format's own attributes; use other names")
    write_arrays(group, {**arrays, "slot_valid": valid})
    group.attrs.update({**(attrs or {}), **own})


def read_btf(group, *, where: str = "material/btf") -> BtfGroup:
    """The ``btf`` group written by :func:`write_btf`."""
    arrays = read_arrays(group, where=where)
    attrs = dict(group.attrs)
    model = btf_from_arrays(arrays, attrs, where=where)
    n_views = len(model.view_dirs_deg)
    valid = arrays.get("slot_valid", np.ones(n_views, bool))
    if valid.shape != (n_views,) or valid.dtype != bool:
        raise MaterialError(
            f"{where}: slot_valid has shape {valid.shape} dtype {valid.dtype}, "
            f"expected ({n_views},) bool"
        )
    version = check_version(attrs, "btf", _READABLE, where=where)
    radiometry = (
        Radiometry.from_attrs(attrs.get("radiometry"), where=where) if version >= 2
        else NOT_RECORDED
    )  # fmt: skip
    return BtfGroup(
        model, valid, str(attrs.get("units", "relative radiance")),
        other_attrs(attrs, "radiometry"), radiometry,
    )  # fmt: skip
