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
    "check_version",
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


def other_attrs(attrs: Mapping[str, Any], *skip: str) -> dict[str, Any]:
    """``attrs`` as a plain dict without the format's own keys and ``skip``."""
    return {k: v for k, v in dict(attrs).items() if k not in _OWN and k not in skip}


def read_arrays(group) -> dict[str, np.ndarray]:
    """Every array directly in ``group``, read into memory."""
    return {name: np.asarray(array[...]) for name, array in group.arrays()}


def require_arrays(arrays: Mapping[str, Any], names, *, where: str) -> None:
    """MaterialError naming ``where`` and the missing ones unless ``arrays`` has ``names``."""
    missing = [n for n in names if n not in arrays]
    if missing:
        raise MaterialError(f"{where}: lacks array(s) {missing}; expected {list(names)}")


def write_arrays(group, arrays: Mapping[str, np.ndarray]) -> None:
    """Create each array of ``arrays`` in ``group`` (zarr's default chunks and codecs)."""
    for name, value in arrays.items():
        group.create_array(name, data=np.asarray(value))
