"""A plain folder of frames with a table of their light and view directions.

``directions.csv`` (header ``file,light_theta_deg,light_phi_deg,view_theta_deg,
view_phi_deg``) or ``directions.toml`` (``[[frame]]`` tables with ``file``,
``light_deg = [θ, φ]``, ``view_deg = [θ, φ]``, and optionally a top-level
``encoding = "srgb" | "linear"``). Directions in degrees, sample frame.
"""

from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass
from pathlib import Path

from rig.errors import ConfigError
from rig.interchange._errors import InterchangeError
from rig.interchange._images import IMAGE_SUFFIXES
from rig.interchange._manifest import MANIFEST
from rig.tomlfile import read_toml

__all__ = ["ENCODINGS", "FolderFrame", "FolderListing", "hemisphere_direction", "list_folder"]

#: how a file's integer values encode radiance
ENCODINGS = ("srgb", "linear")
_CSV_COLUMNS = ("file", "light_theta_deg", "light_phi_deg", "view_theta_deg", "view_phi_deg")
_TABLES = ("directions.csv", "directions.toml")


@dataclass(frozen=True)
class FolderFrame:
    """One frame of the folder and its directions, degrees."""

    path: Path
    light_deg: tuple[float, float]
    view_deg: tuple[float, float]


@dataclass(frozen=True)
class FolderListing:
    """The frames a directions table lists; ``encoding`` when the table says (TOML)."""

    frames: tuple[FolderFrame, ...]
    table: Path
    encoding: str | None


def list_folder(folder) -> FolderListing:
    """The frames of ``folder`` as its directions table lists them.

    Raises InterchangeError naming the table, the row and the field that is
    wrong, a listed file that is missing, or a file the table does not list.
    """
    folder = Path(folder)
    tables = [folder / name for name in _TABLES if (folder / name).is_file()]
    if len(tables) != 1:
        found = "both" if tables else "neither"
        raise InterchangeError(
            f"{folder}: {found} of {' and '.join(_TABLES)}; a plain folder of frames needs "
            "exactly one table of their directions (or use the UBO2003 layout)"
        )
    table = tables[0]
    if table.suffix == ".csv":
        frames, encoding = _read_csv(table), None
    else:
        frames, encoding = _read_toml(table)
    listed = {frame.path.name for frame in frames}
    for path in sorted(folder.iterdir()):
        if path != table and path.name not in listed and path.name != MANIFEST:
            raise InterchangeError(
                f"{path}: not listed in {table.name}; list it or move it out of the folder"
            )
    return FolderListing(tuple(frames), table, encoding)


def _frame(folder: Path, name, light, view, *, where: str) -> FolderFrame:
    if not isinstance(name, str) or not name or Path(name).name != name:
        raise InterchangeError(f"{where}: file = {name!r}: give a file name in the folder")
    path = folder / name
    if path.suffix.lower() not in IMAGE_SUFFIXES:
        raise InterchangeError(f"{where}: file {name!r} is not an image; images are "
                               f"{IMAGE_SUFFIXES}")  # fmt: skip
    if not path.is_file():
        raise InterchangeError(f"{where}: file {name!r} does not exist in {folder}")
    return FolderFrame(path, _angles(light, f"{where}: light"), _angles(view, f"{where}: view"))


def _angles(value, where: str) -> tuple[float, float]:
    try:
        theta, phi = (float(v) for v in value)
    except (TypeError, ValueError, OverflowError):
        raise InterchangeError(f"{where} = {value!r}: give two numbers [θ, φ] in degrees") from None
    return hemisphere_direction(theta, phi, where=where)


def hemisphere_direction(theta: float, phi: float, *, where: str) -> tuple[float, float]:
    """``(θ, φ mod 360)`` degrees of a measured direction; InterchangeError naming
    ``where`` when it is not finite or lies below the horizon (θ > 90°)."""
    if not (math.isfinite(theta) and math.isfinite(phi) and 0.0 <= theta <= 90.0):
        raise InterchangeError(
            f"{where} = ({theta:g}°, {phi:g}°): a measured direction has finite degrees "
            "and 0 ≤ θ ≤ 90 (θ > 90° lies below the horizon)"
        )
    return theta, phi % 360.0


def _read_csv(table: Path) -> list[FolderFrame]:
    try:
        text = table.read_text(encoding="utf-8")
    except UnicodeDecodeError as err:
        line = table.read_bytes()[: err.start].count(b"\n") + 1
        raise InterchangeError(
            f"{table} line {line}: not UTF-8 text (byte {err.object[err.start]:#04x}); save the "
            "table as UTF-8"
        ) from None
    reader = csv.DictReader(io.StringIO(text, newline=""))
    try:
        if tuple(reader.fieldnames or ()) != _CSV_COLUMNS:
            raise InterchangeError(
                f"{table}: header {reader.fieldnames}; expected {','.join(_CSV_COLUMNS)}"
            )
        return [
            _frame(
                table.parent,
                row["file"],
                (row["light_theta_deg"], row["light_phi_deg"]),
                (row["view_theta_deg"], row["view_phi_deg"]),
                where=f"{table} row {number}",
            )
            for number, row in enumerate(reader, start=2)
        ]
    except csv.Error as err:  # a field over the csv module's limit (raised before its line counts)
        raise InterchangeError(
            f"{table} line {reader.line_num + 1}: not a readable CSV row ({err})"
        ) from None


def _read_toml(table: Path) -> tuple[list[FolderFrame], str | None]:
    try:
        data = read_toml(table, "directions table")
    except ConfigError as err:
        raise InterchangeError(str(err)) from err
    unknown = sorted(set(data) - {"frame", "encoding"})
    encoding = data.get("encoding")
    if unknown or encoding not in (None, *ENCODINGS):
        raise InterchangeError(
            f"{table}: keys {unknown}, encoding = {encoding!r}; a directions table has "
            f"[[frame]] tables and optionally encoding = one of {ENCODINGS}"
        )
    frames = []
    for number, row in enumerate(data.get("frame", []), start=1):
        where = f"{table} [[frame]] {number}"
        if not isinstance(row, dict) or set(row) != {"file", "light_deg", "view_deg"}:
            raise InterchangeError(f"{where}: needs exactly file, light_deg, view_deg")
        frames.append(_frame(table.parent, row["file"], row["light_deg"], row["view_deg"],
                             where=where))  # fmt: skip
    return frames, encoding
