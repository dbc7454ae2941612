"""The ``pbr`` group of a material: the BTF fitted by a glTF PBR material, per texel.

The model is glTF 2.0's metallic-roughness material (metallic 0) with
KHR_materials_specular, KHR_materials_sheen and KHR_materials_anisotropy
(``processing.pbr`` fits and evaluates it); every map is on the material's texel
grid, with the fit's error and flags per texel (``docs/material.md``).
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np

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

__all__ = ["PbrFlag", "PbrMaps", "pbr_layers", "read_pbr", "write_pbr"]

VERSION = 1
#: the model, as the glTF extensions name it (stored with the group)
MODEL = (
    "glTF 2.0 metallic-roughness (metallic 0) + KHR_materials_specular + "
    "KHR_materials_sheen + KHR_materials_anisotropy"
)


class PbrFlag(enum.IntFlag):
    """Why a texel's fit deserves less trust (bits of ``flags``; 0: none)."""

    DARK = 1  #: every sample below the dark level: base colour 0, the rest at the priors
    SATURATED = 2  #: some samples clipped, left out of the fit
    NO_SPECULAR = 4  #: no specular signal: roughness and anisotropy stay at their priors
    SINGLE_LIGHT = 8  #: one light direction only
    ONE_ELEVATION = 16  #: every light at one elevation: gloss and colour trade off
    NORMAL_UNFIT = 32  #: lights too few or coplanar to fit the normal: it stays the start


@dataclass(frozen=True)
class PbrMaps:
    """The fitted maps on the N × N texel grid (float32 unless said).

    Attributes
    ----------
    base_colour, sheen_colour : (N, N, C) linear, [0, 1]
    roughness, specular, sheen_roughness, anisotropy : (N, N), [0, 1]
    specular_colour : (N, N) grey ``specularColorFactor``, ≥ 0
    anisotropy_deg : (N, N) direction of the lobe's stretch, degrees from +x towards +y
    normal : (N, N, 3) unit, sample frame (= tangent frame)
    height_mm : (N, N) height over the reference plane, mm
    error_rmse : (N, N) RMS difference fit − BTF over the texel's samples (BTF units)
    flags : (N, N) uint8 :class:`PbrFlag` bits
    attrs : dict
        ``height_source`` ("ps", "mdf" or "fitted normals"), ``psnr_db``, ``peak``,
        ``units`` and the fit's options.
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
    height_mm: np.ndarray
    error_rmse: np.ndarray
    flags: np.ndarray
    attrs: dict[str, Any] = field(default_factory=dict)

    @property
    def size(self) -> int:
        return self.normal.shape[0]


_ARRAYS = tuple(f.name for f in fields(PbrMaps) if f.name != "attrs")
_UNIT = ("roughness", "specular", "sheen_roughness", "anisotropy", "base_colour", "sheen_colour")


def pbr_layers(maps: PbrMaps) -> np.ndarray:
    """The four RGBA layers the shaders read (``render/shaders/pbr.glsl``), (4, N, N, 4)
    float32, texel row 0 at +y: base colour + roughness; sheen colour + sheen roughness;
    normal + specular; (cos φ, sin φ) of the anisotropy direction, strength, specular colour.
    A grey material's colours repeat in R, G and B."""

    def rgb(v):
        return np.repeat(v, 3, axis=-1) if v.shape[-1] == 1 else v

    phi = np.deg2rad(maps.anisotropy_deg.astype(np.float64))
    return np.stack([
        np.dstack([rgb(maps.base_colour), maps.roughness]),
        np.dstack([rgb(maps.sheen_colour), maps.sheen_roughness]),
        np.dstack([maps.normal, maps.specular]),
        np.dstack([np.cos(phi), np.sin(phi), maps.anisotropy, maps.specular_colour]),
    ]).astype(np.float32)  # fmt: skip


def write_pbr(group, maps: PbrMaps) -> None:
    """Write ``maps`` into the empty zarr ``group`` (the material's ``pbr``)."""
    arrays = _checked({name: getattr(maps, name) for name in _ARRAYS}, where="pbr")
    clash = sorted(set(maps.attrs) & {"format", "version", "model", "size", "flag_bits"})
    if clash:
        raise MaterialError(f"pbr attrs {clash}: the format's own attributes; use other names")
    write_arrays(group, arrays)
    group.attrs.update({
        **maps.attrs, **format_attrs("pbr", VERSION), "model": MODEL, "size": maps.size,
        "flag_bits": {flag.name: int(flag) for flag in PbrFlag},
    })  # fmt: skip


def read_pbr(group, *, where: str = "material/pbr") -> PbrMaps:
    """The maps of a ``pbr`` group written by :func:`write_pbr`."""
    check_version(dict(group.attrs), "pbr", (VERSION,), where=where)
    arrays = _checked(read_arrays(group, where=where), where=where)
    return PbrMaps(**arrays, attrs=other_attrs(group.attrs, "model", "size", "flag_bits"))


def _checked(arrays: dict[str, Any], *, where: str) -> dict[str, np.ndarray]:
    """The maps in their stored dtypes; MaterialError naming the array otherwise."""
    require_arrays(arrays, _ARRAYS, where=where)
    normal = finite_floats("normal", arrays["normal"], where=where).astype(np.float32)
    if normal.ndim != 3 or normal.shape[2] != 3 or normal.shape[0] != normal.shape[1]:
        raise MaterialError(f"{where}: normal has shape {normal.shape}, expected (N, N, 3)")
    n = normal.shape[0]
    out = {"normal": normal, "flags": as_uint8("flags", arrays["flags"], where=where)}
    for name in _ARRAYS:
        if name in out:
            continue
        value = finite_floats(name, arrays[name], where=where).astype(np.float32)
        coloured = name in ("base_colour", "sheen_colour")
        if value.shape[:2] != (n, n) or value.ndim != (3 if coloured else 2):
            want = f"({n}, {n}, C)" if coloured else f"({n}, {n})"
            raise MaterialError(f"{where}: {name} has shape {value.shape}, expected {want}")
        if name in _UNIT and value.size and (value.min() < -1e-6 or value.max() > 1 + 1e-6):
            raise MaterialError(
                f"{where}: {name} spans {value.min():.4g}…{value.max():.4g}; expected [0, 1]"
            )
        out[name] = value
    if out["flags"].shape != (n, n):
        raise MaterialError(f"{where}: flags has shape {out['flags'].shape}, expected ({n}, {n})")
    if out["base_colour"].shape != out["sheen_colour"].shape:
        raise MaterialError(
            f"{where}: base_colour {out['base_colour'].shape} and sheen_colour "
            f"{out['sheen_colour'].shape} differ; give both the same channels"
        )
    length = np.linalg.norm(normal, axis=-1)
    if length.size and float(np.abs(length - 1.0).max()) > 1e-3:
        raise MaterialError(f"{where}: normal holds vectors of length {length.min():.4g}…; unit")
    return out
