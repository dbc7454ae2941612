"""What every versioned group of a material shares: its ``format``/``version``
attributes, and reading or writing its arrays.

A group is any zarr v3 group (``zarr.Group``): one in an archive's
``material/``, in a standalone material store, or a flat-field store.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from rig.material._errors import MaterialError

__all__ = [
    "FORMAT_PREFIX",
    "as_uint8",
    "check_version",
    "finite_floats",
    "format_attrs",
    "other_attrs",
    "read_arrays",
    "require_arrays",
    "write_arrays",
]

#: ``format`` of a group is this prefix + the group's kind (``btf``, ``ps``…).
FORMAT_PREFIX = "btfrig.material."
_OWN = ("format", "version")


def format_attrs(kind: str, version: int) -> dict[str, Any]:
    """The ``format``/``version`` attributes a writer stamps on a ``kind`` group."""
    return {"format": FORMAT_PREFIX + kind, "version": version}


def check_version(
    attrs: Mapping[str, Any], kind: str, readable: tuple[int, ...], *, where: str
) -> int:
    """The version of a ``kind`` group with attributes ``attrs``, if this btfrig reads it.

    A group without ``format`` and ``version`` is version 0 (written before the
    format was versioned) when 0 is in ``readable``. MaterialError names
    ``where`` and the version found otherwise.
    """
    expected = FORMAT_PREFIX + kind
    if "format" not in attrs and "version" not in attrs:
        version = 0
    else:
        if attrs.get("format") != expected:
            raise MaterialError(
                f"{where}: attribute format = {attrs.get('format')!r}, expected {expected!r}"
            )
        version = attrs.get("version")
    if version not in readable:
        shown = ", ".join(str(v) for v in readable)
        found = "no format/version attributes" if version == 0 else f"version {version!r}"
        raise MaterialError(f"{where}: {kind} group has {found}; this btfrig reads version {shown}")
    return int(version)


def as_uint8(name: str, value, *, where: str) -> np.ndarray:
    """``value`` as uint8 (codes, counts); MaterialError naming it when it does not fit."""
    array = np.asarray(value)
    if array.dtype == np.uint8:
        return array
    if array.size and (
        not np.issubdtype(array.dtype, np.integer) or array.min() < 0 or array.max() > 255
    ):
        raise MaterialError(
            f"{where}: {name} ({array.dtype}) must hold whole numbers in 0..255 (uint8)"
        )
    return array.astype(np.uint8)


def other_attrs(attrs: Mapping[str, Any], *skip: str) -> dict[str, Any]:
    """``attrs`` as a plain dict without the format's own keys and ``skip``."""
    return {k: v for k, v in dict(attrs).items() if k not in _OWN and k not in skip}


def finite_floats(name: str, value, *, where: str) -> np.ndarray:
    """``value`` as stored when it is a float array of finite values; MaterialError
    naming ``where``, the array and what it holds otherwise (a damaged material
    would render black or export black images)."""
    array = np.asarray(value)
    if array.dtype.kind != "f":
        raise MaterialError(f"{where}: {name} has dtype {array.dtype}; expected float values")
    bad = array.size - np.count_nonzero(np.isfinite(array))
    if bad:
        raise MaterialError(
            f"{where}: {name} holds NaN or inf ({bad} of {array.size} values); a material "
            "holds finite values (run `rig process` again for a damaged one)"
        )
    return array


def read_arrays(group, *, where: str) -> dict[str, np.ndarray]:
    """Every array directly in ``group``, read into memory; MaterialError naming
    ``where`` and the array when one cannot be read (a truncated or corrupt chunk,
    a dtype zarr does not know)."""
    arrays = {}
    reading = "the list of its arrays"
    try:
        for name, array in group.arrays():
            reading = f"array {name!r}"
            arrays[name] = np.asarray(array[...])
    except Exception as err:  # zarr and its codecs raise their own types for damaged files
        raise MaterialError(
            f"{where}: {reading} cannot be read ({type(err).__name__}: {err}); the material is "
            "damaged: run `rig process` again for it"
        ) from err
    return arrays


def require_arrays(arrays: Mapping[str, Any], names, *, where: str) -> None:
    """MaterialError naming ``where`` and the missing ones unless ``arrays`` has ``names``."""
    missing = [n for n in names if n not in arrays]
    if missing:
        raise MaterialError(f"{where}: lacks array(s) {missing}; expected {list(names)}")


def write_arrays(group, arrays: Mapping[str, np.ndarray]) -> None:
    """Create each array of ``arrays`` in ``group`` (zarr's default chunks and codecs)."""
    for name, value in arrays.items():
        group.create_array(name, data=np.asarray(value))
