"""The Bonn UBO2003 BTF folder layout: names, reading a folder, writing one.

One folder per view, ``tv{θv:03d}_pv{φv:03d}``; in it one image per light,
``{index:05d} tl{θl:03d} pl{φl:03d} tv{θv:03d} pv{φv:03d}.{jpg|png}``; angles
in whole degrees in the sample frame (θ from the normal, φ azimuth), images
the rectified normtextures, 8-bit sRGB-encoded.

References
----------
.. [1] Sattler, Sarlette, Klein. "Efficient and realistic visualization of
   cloth." EGSR 2003 (seed 000): the H1 sampling and the normtextures.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rig.geometry import Sampling
from rig.interchange._directions import hemisphere_direction
from rig.interchange._errors import InterchangeError
from rig.interchange._images import to_srgb, write_image
from rig.interchange._manifest import MANIFEST, write_manifest

__all__ = [
    "UboFrame",
    "UboListing",
    "list_ubo2003",
    "ubo2003_file",
    "ubo2003_view_folder",
    "write_ubo2003",
]

_VIEW = re.compile(r"tv(\d{3})_pv(\d{3})")
_FILE = re.compile(r"(\d{5}) tl(\d{3}) pl(\d{3}) tv(\d{3}) pv(\d{3})\.(jpg|jpeg|png)", re.I)
_FILE_FORM = "'{index:05d} tl{θl:03d} pl{φl:03d} tv{θv:03d} pv{φv:03d}.jpg|png'"


def _whole(value: float, what: str) -> int:
    degrees = round(float(value))
    if not 0 <= degrees <= 999:
        raise InterchangeError(f"{what} = {value}°: UBO2003 names hold whole degrees 0…999")
    return int(degrees) % 360 if what.startswith("φ") else int(degrees)


def ubo2003_view_folder(view_deg) -> str:
    """The folder name of view (θ, φ) in degrees, e.g. ``tv015_pv060``."""
    return f"tv{_whole(view_deg[0], 'θv'):03d}_pv{_whole(view_deg[1], 'φv'):03d}"


def ubo2003_file(index: int, light_deg, view_deg, *, suffix: str = ".png") -> str:
    """The file name of light ``index`` (θl, φl) seen from view (θv, φv)."""
    tl, pl = _whole(light_deg[0], "θl"), _whole(light_deg[1], "φl")
    view = ubo2003_view_folder(view_deg).replace("_", " ")
    return f"{index:05d} tl{tl:03d} pl{pl:03d} {view}{suffix}"


@dataclass(frozen=True)
class UboFrame:
    """One image of the layout: its file, its light's index and directions (degrees)."""

    path: Path
    index: int
    light_deg: tuple[float, float]
    view_deg: tuple[float, float]


@dataclass(frozen=True)
class UboListing:
    """What a UBO2003 folder holds, and what it lacks.

    ``frames`` are ordered by view folder, then light index. ``gaps`` says in
    words which views lack which lights (empty for a complete set).
    """

    frames: tuple[UboFrame, ...]
    views_deg: tuple[tuple[float, float], ...]
    lights_deg: tuple[tuple[float, float], ...]
    gaps: tuple[str, ...]


def list_ubo2003(folder) -> UboListing:
    """The frames of a UBO2003 folder, from names alone (no image is read).

    Raises InterchangeError naming the first entry that is not a view folder
    (``tv…_pv…``), not a frame name of that view, a direction below the
    horizon (θ > 90°), or an empty layout.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise InterchangeError(f"{folder}: not a folder; expected a UBO2003 folder of views")
    frames: list[UboFrame] = []
    views: list[tuple[float, float]] = []
    for entry in sorted(folder.iterdir()):
        if entry.name == MANIFEST and entry.is_file():
            continue
        match = _VIEW.fullmatch(entry.name)
        if match is None or not entry.is_dir():
            raise InterchangeError(
                f"{entry}: not a UBO2003 view folder; expected folders named tv{{θv:03d}}_pv"
                f"{{φv:03d}} (e.g. tv015_pv060) and nothing else"
            )
        view = (float(match[1]), float(match[2]))
        hemisphere_direction(*view, where=f"{entry}: view")
        views.append(view)
        frames.extend(_view_frames(entry, view))
    if not frames:
        raise InterchangeError(f"{folder}: no images in the UBO2003 layout here")
    lights = sorted({f.light_deg for f in frames})
    return UboListing(tuple(frames), tuple(views), tuple(lights), _gaps(frames, views, lights))


def _view_frames(folder: Path, view: tuple[float, float]) -> Iterator[UboFrame]:
    indices: dict[int, Path] = {}
    for path in sorted(folder.iterdir()):
        match = _FILE.fullmatch(path.name)
        if match is None or not path.is_file():
            raise InterchangeError(f"{path}: not a UBO2003 image name; expected {_FILE_FORM}")
        index = int(match[1])
        if (float(match[4]), float(match[5])) != view:
            raise InterchangeError(
                f"{path}: names view tv{match[4]} pv{match[5]} but lies in view folder "
                f"{folder.name}"
            )
        if index in indices:
            raise InterchangeError(f"{path}: light index {index} also names {indices[index].name}")
        indices[index] = path
        light = hemisphere_direction(float(match[2]), float(match[3]), where=f"{path}: light")
        yield UboFrame(path, index, light, view)


def _gaps(frames, views, lights) -> tuple[str, ...]:
    have: dict[tuple[float, float], set] = {view: set() for view in views}
    for frame in frames:
        have[frame.view_deg].add(frame.light_deg)
    gaps = list(_sampling_gaps(views, lights))
    for view in views:
        missing = [light for light in lights if light not in have[view]]
        if missing:
            gaps.append(
                f"view ({view[0]:g}°, {view[1]:g}°): {len(missing)} of {len(lights)} lights "
                f"missing: {_shown(missing)}"
            )
    return tuple(gaps)


def _sampling_gaps(views, lights) -> Iterator[str]:
    """The views and lights a set lacks of the seed's sampling (H1 or H2) that holds
    all of its directions; nothing for a set of other directions."""
    for name in ("H1", "H2"):
        table = {(float(t), float(p)) for t, p in Sampling.named(name).directions}
        if set(views) <= table and set(lights) <= table:
            for what, present in (("views", set(views)), ("lights", set(lights))):
                missing = sorted(table - present)
                if missing:
                    yield (f"{len(missing)} of the {len(table)} {what} of the {name} sampling "
                           f"missing: {_shown(missing)}")  # fmt: skip
            return


def _shown(directions) -> str:
    shown = ", ".join(f"({t:g}°, {p:g}°)" for t, p in directions[:6])
    return shown + (f" and {len(directions) - 6} more" if len(directions) > 6 else "")


def write_ubo2003(
    out,
    views_deg,
    lights_deg,
    normtexture: Callable[[int, int], np.ndarray | None],
    *,
    white: float,
    manifest: dict,
    progress: Callable[[int, int], None] | None = None,
) -> Path:
    """Write normtextures in the UBO2003 layout into the existing empty folder ``out``.

    ``normtexture(view, light)`` gives the (N, N, C) linear values of view slot
    ``view`` under light ``light``, or None for one there is not (a gap, listed
    in the manifest); each is scaled by 1/``white``, sRGB-encoded to 8 bits and
    written as PNG (lossless; UBO2003 readers take .png names). Light ``i`` is
    file index ``i``. ``manifest`` (plus ``white``, the layout
    and the encoding) goes to ``manifest.json``. Returns the manifest's path.
    """
    out = Path(out)
    if not (np.isfinite(white) and white > 0):
        raise InterchangeError(f"white = {white}: the linear value written as 255 must be > 0")
    folders = [ubo2003_view_folder(view) for view in views_deg]
    if len(set(folders)) < len(folders):
        twice = next(name for name in folders if folders.count(name) > 1)
        same = [tuple(map(float, v)) for v, name in zip(views_deg, folders, strict=True)
                if name == twice]  # fmt: skip
        raise InterchangeError(
            f"views {same} share the UBO2003 folder {twice}: the layout names views in whole "
            "degrees; export a sampling whose views differ by a degree or more"
        )
    total, done, gaps = len(views_deg) * len(lights_deg), 0, []
    for j, view in enumerate(views_deg):
        folder = out / folders[j]
        folder.mkdir()
        for i, light in enumerate(lights_deg):
            texture = normtexture(j, i)
            done += 1
            if texture is None:
                gaps.append({"view_deg": list(map(float, view)), "light_deg":
                             list(map(float, light))})  # fmt: skip
            else:
                scaled = np.asarray(texture, np.float64) / white
                write_image(folder / ubo2003_file(i, light, view), to_srgb(scaled))
            if progress is not None:
                progress(done, total)
    document = {
        **manifest, "layout": "ubo2003", "encoding": "srgb", "white": float(white),
        "white_means": "linear value of 255 (the importer multiplies by it)",
        "views_deg": [list(map(float, v)) for v in views_deg],
        "lights_deg": [list(map(float, v)) for v in lights_deg],
        "gaps": gaps,
    }  # fmt: skip
    return write_manifest(out, document)
