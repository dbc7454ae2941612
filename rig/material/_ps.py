"""The ``ps`` group of a material: photometric-stereo maps, one subgroup per view.

``ps/<view>/`` holds ``normals``, ``albedo``, ``valid``, ``reason`` and
``height_mm`` on the texel grid, and the view's attributes (``view_deg``, the
camera, the steps…) with the radiometric corrections its frames had
(``radiometry``, from version 2). Version 0 is the layout written before the
group carried ``format``/``version``: the same arrays, no ``view_deg``; versions
0 and 1 have no ``radiometry`` and read as ``NOT_RECORDED``.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass, field
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
from rig.material._radiometry import NOT_RECORDED, Radiometry

__all__ = ["PsView", "read_ps", "write_ps"]

VERSION = 2
_ARRAYS = ("normals", "albedo", "valid", "reason", "height_mm")
#: how far from 1 a valid texel's normal may be (float32 storage of a unit vector)
_UNIT_TOL = 1e-3
_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.\-]*")


@dataclass(frozen=True)
class PsView:
    """One view's photometric-stereo maps on the N × N texel grid.

    Attributes
    ----------
    name : str
        The view's name, e.g. ``cam0_tt000.0`` (camera, turntable angle).
    normals : (N, N, 3) float32
        Unit normals in the sample frame.
    albedo : (N, N, C) float32
        Diffuse albedo, C = 3 (RGB) or 1.
    valid : (N, N) bool
        Texels with a trustworthy solve.
    reason : (N, N) uint8
        ``processing.photometric.Reason`` per texel (0 where valid).
    height_mm : (N, N) float32
        Integrated height over the reference plane.
    view_deg : (θ, φ) or None
        The camera's view direction in the sample frame, degrees; None where
        the group does not record it (version 0).
    attrs : dict
        The view's other attributes (camera, turntable_deg, steps, lamps…).
    radiometry : Radiometry
        The corrections its frames had before the solve (``NOT_RECORDED`` for
        groups of version 0 and 1).
    """

    name: str
    normals: np.ndarray
    albedo: np.ndarray
    valid: np.ndarray
    reason: np.ndarray
    height_mm: np.ndarray
    view_deg: tuple[float, float] | None = None
    attrs: dict[str, Any] = field(default_factory=dict)
    radiometry: Radiometry = field(default_factory=Radiometry)

    @property
    def size(self) -> int:
        return self.normals.shape[0]


def write_ps(group, views: Sequence[PsView], *, attrs: dict[str, Any] | None = None) -> None:
    """Write ``views`` into the empty zarr ``group`` (the material's ``ps``).

    ``attrs`` are extra JSON-able attributes of the whole group (the solver…).
    """
    if not views:
        raise MaterialError("ps: no views to write; give at least one PsView")
    sizes = {v.size for v in views}
    if len(sizes) != 1:
        raise MaterialError(f"ps: the views use different texel grids N = {sorted(sizes)}")
    names = [v.name for v in views]
    for name in names:
        if not isinstance(name, str) or not _NAME.fullmatch(name):
            raise MaterialError(
                f"ps view name {name!r}: use letters, digits, '_', '-' and '.', "
                "starting with a letter, digit or '_'"
            )
    if len(set(names)) != len(names):
        raise MaterialError(f"ps: view names repeat: {sorted(names)}")
    for view in views:
        where = f"ps view {view.name!r}"
        arrays = _checked(_arrays_of(view), where=where)
        view_deg = _view_deg(view.view_deg, where=where)
        sub = group.create_group(view.name)
        write_arrays(sub, arrays)
        sub.attrs.update({
            **view.attrs, "view_deg": None if view_deg is None else list(view_deg),
            "radiometry": view.radiometry.to_attrs(),
        })  # fmt: skip
    group.attrs.update({**(attrs or {}), **format_attrs("ps", VERSION), "size": sizes.pop()})


def read_ps(group, *, where: str = "material/ps") -> dict[str, PsView]:
    """The views of a ``ps`` group (version 0, 1 or 2), by name."""
    version = check_version(dict(group.attrs), "ps", (0, 1, VERSION), where=where)
    views = {}
    for name, sub in sorted(group.groups()):
        here = f"{where}/{name}"
        arrays = _checked(read_arrays(sub, where=here), where=here)
        attrs = dict(sub.attrs)
        radiometry = (
            Radiometry.from_attrs(attrs.get("radiometry"), where=here) if version >= 2
            else NOT_RECORDED
        )  # fmt: skip
        views[name] = PsView(
            name, **arrays, view_deg=_view_deg(attrs.get("view_deg"), where=here),
            attrs=other_attrs(attrs, "view_deg", "radiometry"), radiometry=radiometry,
        )  # fmt: skip
    if not views:
        raise MaterialError(f"{where}: holds no views")
    return views


def _arrays_of(view: PsView) -> dict[str, np.ndarray]:
    return {name: getattr(view, name) for name in _ARRAYS}


def _view_deg(value, *, where: str) -> tuple[float, float] | None:
    if value is None:
        return None
    angles = np.asarray(value, dtype=np.float64)
    if angles.shape != (2,) or not np.all(np.isfinite(angles)) or not 0 <= angles[0] <= 90:
        raise MaterialError(f"{where}: view_deg = {value!r}; expected [theta, phi], θ in [0, 90]")
    return float(angles[0]), float(angles[1])


def _checked(arrays: dict[str, Any], *, where: str) -> dict[str, np.ndarray]:
    """The five maps in their stored dtypes; MaterialError naming the array otherwise."""
    require_arrays(arrays, _ARRAYS, where=where)
    normals = finite_floats("normals", arrays["normals"], where=where)
    if normals.ndim != 3 or normals.shape[2] != 3 or normals.shape[0] != normals.shape[1]:
        raise MaterialError(f"{where}: normals has shape {normals.shape}, expected (N, N, 3)")
    n = normals.shape[0]
    expected = {"albedo": (n, n), "valid": (n, n), "reason": (n, n), "height_mm": (n, n)}
    for name, shape in expected.items():
        got = np.shape(arrays[name])
        if got[:2] != shape or (name == "albedo") != (len(got) == 3):
            want = f"({n}, {n}, C)" if name == "albedo" else str(shape)
            raise MaterialError(f"{where}: {name} has shape {got}, expected {want}")
    if np.shape(arrays["albedo"])[2] not in (1, 3):
        raise MaterialError(f"{where}: albedo has {np.shape(arrays['albedo'])[2]} channels; 1 or 3")
    valid = np.asarray(arrays["valid"])
    if valid.dtype != bool:
        raise MaterialError(f"{where}: valid has dtype {valid.dtype}, expected bool")
    out = {
        "normals": normals.astype(np.float32),
        "albedo": finite_floats("albedo", arrays["albedo"], where=where).astype(np.float32),
        "valid": valid,
        "reason": as_uint8("reason", arrays["reason"], where=where),
        "height_mm": finite_floats("height_mm", arrays["height_mm"], where=where).astype(
            np.float32
        ),
    }
    for name in ("normals", "albedo", "height_mm"):
        if not np.all(np.isfinite(out[name])):  # float64 beyond float32's range
            raise MaterialError(f"{where}: {name} holds NaN or inf; store finite values")
    length = np.linalg.norm(out["normals"][valid], axis=-1)
    if length.size and float(np.abs(length - 1.0).max()) > _UNIT_TOL:
        raise MaterialError(
            f"{where}: normals of valid texels have lengths {length.min():.4g}…{length.max():.4g}; "
            "expected unit vectors"
        )
    return out
