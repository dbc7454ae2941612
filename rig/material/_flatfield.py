"""Flat fields: each lamp's fall-off on the white target, beside a calibration file.

``rig calibrate lamps`` writes ``CAL.flatfield.zarr``, a zarr v3 group with
``format = "btfrig.material.flatfield"``, ``version``, ``camera`` and
``lamps``, and one array ``falloff`` (L, H, W) float32. Version 0 is the
``CAL.flatfield.npz`` written before (arrays ``camera``, ``lamps``, ``falloff``).

A session archive keeps its own copy under ``calibration/`` with the name the
calibration file gives it (:func:`archive_flat_field_path`), so that
re-processing finds it wherever the archive is moved.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rig.archive._material import replace_result
from rig.material._errors import MaterialError
from rig.material._groups import check_version, format_attrs

__all__ = [
    "FlatFieldMaps",
    "archive_flat_field_path",
    "copy_flat_field",
    "read_flat_field",
    "write_flat_field",
]

VERSION = 1


@dataclass(frozen=True)
class FlatFieldMaps:
    """Each lamp's fall-off on the white target as ``camera`` sees it.

    ``falloff`` (L, H, W) float32: lamp ``lamps[i]``'s image over its value at
    the target's centre (1 there), in the camera's pixels.
    """

    camera: str
    lamps: tuple[str, ...]
    falloff: np.ndarray


def write_flat_field(path: str | os.PathLike, maps: FlatFieldMaps) -> Path:
    """Write ``maps`` as the store ``path``, replacing an earlier one whole; returns ``path``."""
    import zarr

    path = Path(path)
    falloff = _checked(maps, where=str(path))
    with replace_result(path.parent, path.name, fsync=True) as tmp:
        group = zarr.open_group(tmp, mode="w", zarr_format=3)
        group.create_array("falloff", data=falloff)
        group.attrs.update(
            {**format_attrs("flatfield", VERSION), "camera": maps.camera, "lamps": list(maps.lamps)}
        )
    return path


def read_flat_field(path: str | os.PathLike) -> FlatFieldMaps:
    """The flat fields at ``path``: a store (version 1) or an older ``.npz`` (version 0)."""
    import zarr

    path = Path(path)
    if path.is_file() and path.suffix == ".npz":
        with np.load(path) as data:
            missing = sorted({"camera", "lamps", "falloff"} - set(data.files))
            if missing:
                raise MaterialError(f"{path}: lacks array(s) {missing} of a flat-field file")
            maps = FlatFieldMaps(
                str(data["camera"]), tuple(str(x) for x in data["lamps"]), data["falloff"]
            )
    elif (path / "zarr.json").is_file():
        group = zarr.open_group(path, mode="r")
        attrs = dict(group.attrs)
        check_version(attrs, "flatfield", (VERSION,), where=str(path))
        if "falloff" not in group:
            raise MaterialError(f"{path}: lacks the array falloff (L, H, W)")
        lamps = tuple(str(x) for x in attrs.get("lamps", []))
        maps = FlatFieldMaps(str(attrs.get("camera", "")), lamps, group["falloff"][...])
    else:
        raise MaterialError(
            f"{path}: no flat fields here; expected a CAL.flatfield.zarr store "
            "(rig calibrate lamps) or an older CAL.flatfield.npz"
        )
    return FlatFieldMaps(maps.camera, maps.lamps, _checked(maps, where=str(path)))


def archive_flat_field_path(archive_path: str | os.PathLike, name: str) -> Path:
    """Where the archive at ``archive_path`` keeps its copy of the flat fields ``name``
    (the calibration's ``lamps_flat_field``)."""
    if Path(name).name != name or name in ("", ".", "..", "zarr.json"):
        raise MaterialError(
            f"lamps_flat_field = {name!r}: expected a store name beside the calibration "
            "file (e.g. calibration.flatfield.zarr), not a path"
        )
    return Path(archive_path) / "calibration" / name


def copy_flat_field(
    calibration_path: str | os.PathLike, name: str, archive_path: str | os.PathLike
) -> Path:
    """Copy the flat fields ``name`` beside the calibration file into the archive;
    returns the copy's path. MaterialError naming the store when it does not read."""
    maps = read_flat_field(Path(calibration_path).parent / name)
    return write_flat_field(archive_flat_field_path(archive_path, name), maps)


def _checked(maps: FlatFieldMaps, *, where: str) -> np.ndarray:
    falloff = np.asarray(maps.falloff, np.float32)
    if falloff.ndim != 3 or len(falloff) != len(maps.lamps) or len(falloff) == 0:
        raise MaterialError(
            f"{where}: falloff has shape {falloff.shape} for lamps {list(maps.lamps)}; "
            "expected (L, H, W), one map per lamp"
        )
    if not maps.camera:
        raise MaterialError(f"{where}: camera is empty; name the camera that saw the target")
    if not np.all(np.isfinite(falloff)):
        raise MaterialError(f"{where}: falloff holds NaN or inf; store finite values")
    return falloff
