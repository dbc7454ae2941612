"""The BTF part of a material as plain arrays + attributes (``docs/material.md``).

:func:`to_arrays` gives the arrays and JSON-able attributes that go into the
archive's ``material/btf`` group; :func:`from_arrays` rebuilds the model. No
I/O here: the archive (``rig.archive``) writes and reads the group.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from processing.btf._errors import BtfError
from processing.btf._model import CompressedBTF, GlobalSVD, check_directions

__all__ = ["FORMAT", "VERSION", "from_arrays", "to_arrays"]

FORMAT = "btfrig.material.btf"
VERSION = 1
_TEXTURE = np.float16


def _texture(name: str, values: np.ndarray) -> np.ndarray:
    v = np.asarray(values)
    limit = float(np.finfo(_TEXTURE).max)
    peak = float(np.abs(v).max(initial=0.0))
    if not np.isfinite(peak) or peak > limit:
        raise BtfError(
            f"{name} reaches {peak:.4g}, beyond float16 (max {limit:.4g}); scale the BTF "
            "(e.g. to radiance in [0, 1]) before compressing"
        )
    return v.astype(_TEXTURE)


def to_arrays(
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
        raise BtfError(f"model: expected CompressedBTF or GlobalSVD, got {type(model).__name__}")
    attrs = {
        "format": FORMAT,
        "version": VERSION,
        "kind": kind,
        "components": int(model.components),
        "size": int(model.size),
        "channels": int(channels),
        "units": str(units),
        "angles": "degrees, sample frame, theta from +z, phi from +x towards +y",
        "rank": int(model.rank) if kind == "svd" else None,
    }
    return arrays, attrs


def from_arrays(arrays: dict[str, np.ndarray], attrs: dict[str, Any]) -> CompressedBTF | GlobalSVD:
    """Rebuild the model written by :func:`to_arrays` (float16 textures stay float16)."""
    if attrs.get("format") != FORMAT:
        raise BtfError(f"attrs['format'] = {attrs.get('format')!r}: expected {FORMAT!r}")
    if attrs.get("version") != VERSION:
        raise BtfError(
            f"material btf version {attrs.get('version')!r}: this btfrig reads version {VERSION}"
        )
    kind = attrs.get("kind")
    needed = {
        "pca": ("mean", "basis", "weights", "singular_values", "rank"),
        "svd": ("eigenmaps", "weights", "singular_values"),
    }.get(kind)
    if needed is None:
        raise BtfError(f"attrs['kind'] = {kind!r}: valid are 'pca' and 'svd'")
    missing = [k for k in ("view_dirs_deg", "light_dirs_deg", *needed) if k not in arrays]
    if missing:
        raise BtfError(f"material btf ({kind}) lacks arrays {missing}")
    views = check_directions("view_dirs_deg", arrays["view_dirs_deg"])
    lights = check_directions("light_dirs_deg", arrays["light_dirs_deg"])
    a = {k: np.asarray(arrays[k]) for k in needed}
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
        for name, shape in expected.items():
            if a[name].shape != shape:
                raise BtfError(f"material btf: {name} has shape {a[name].shape}, expected {shape}")
        return CompressedBTF(
            views, lights, a["mean"], a["basis"], a["weights"], a["singular_values"], a["rank"]
        )
    c = a["eigenmaps"].shape[0]
    if a["eigenmaps"].ndim != 5 or a["eigenmaps"].shape[1] != n_lights:
        raise BtfError(
            f"material btf: eigenmaps has shape {a['eigenmaps'].shape}, expected "
            f"(c, {n_lights}, N, N, C)"
        )
    if a["weights"].shape != (n_views, c):
        raise BtfError(
            f"material btf: weights has shape {a['weights'].shape}, expected {(n_views, c)}"
        )
    rank = int(attrs.get("rank") or c)
    return GlobalSVD(views, lights, a["eigenmaps"], a["weights"], a["singular_values"], rank)
