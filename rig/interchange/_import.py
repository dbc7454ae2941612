"""`rig import`: a folder of rectified BTF images into a session archive.

The archive's frames are the normtextures as float32 linear values (8-bit
sRGB-encoded images decoded to linear, as the plan's ``frames`` entry says),
one ``btf`` step per image with its light and view direction, all from one
pseudo-camera ``normtexture``. ``rig process --stages btf`` sees from the plan
that the frames are already rectified and skips registration.
"""

from __future__ import annotations

import json
import math
import shutil
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from rig.archive import Archive, FrameFormat, StepRecord
from rig.config import Holder
from rig.interchange._directions import ENCODINGS, list_folder
from rig.interchange._errors import InterchangeError
from rig.interchange._images import read_image, srgb_decode
from rig.interchange._manifest import MANIFEST
from rig.interchange._ubo2003 import list_ubo2003

__all__ = ["NORMTEXTURE_CAMERA", "ImportReport", "import_folder", "imported_normtextures"]

#: the camera name of an imported archive's frames
NORMTEXTURE_CAMERA = "normtexture"
_DEFAULT_SAMPLE_MM = 100.0
#: rows of an image converted to linear values at once
_BAND_ROWS = 256
#: progress(frames done, frames in all)
Progress = Callable[[int, int], None]


def imported_normtextures(plan: Mapping[str, Any]) -> bool:
    """Whether an archive's frames are rectified normtextures (an imported archive)."""
    frames = plan.get("frames")
    return isinstance(frames, Mapping) and frames.get("content") == "normtexture"


@dataclass(frozen=True)
class ImportReport:
    """What an import wrote: frames, view slots × lights, image shape, the sample's
    side (mm) and the gaps."""

    archive: Path
    layout: str
    frames: int
    views: int
    lights: int
    shape: tuple[int, int, int]
    encoding: str
    sample_mm: float
    gaps: tuple[str, ...]


def import_folder(
    folder,
    out,
    *,
    sample_mm: float | None = None,
    encoding: str | None = None,
    progress: Progress | None = None,
) -> ImportReport:
    """Import a UBO2003-layout folder, or a plain folder with ``directions.csv|toml``.

    Parameters
    ----------
    folder : path of the data set
    out : the archive to create (must not exist)
    sample_mm : side of the square sample area the images cover, mm; default
        the ``sample_mm`` of a btfrig export's manifest, else 100
    encoding : ``"srgb"`` or ``"linear"``: how the files' integers encode
        radiance; default sRGB for 8-bit files and UBO2003, linear otherwise
        (OpenEXR is always linear)

    Raises
    ------
    InterchangeError
        Names the file: an unparseable name or a direction below the horizon,
        a non-image, an image of another size or channel count than the first,
        an unreadable, oversized, non-finite or partly transparent one.
    """
    folder, out = Path(folder), Path(out)
    if out.exists():
        raise InterchangeError(f"{out}: already exists; give the archive a new path")
    manifest = _manifest(folder)
    if sample_mm is None:
        sample_mm = manifest.get("sample_mm", _DEFAULT_SAMPLE_MM)
    if not (isinstance(sample_mm, int | float) and 0 < sample_mm < 1e5):
        raise InterchangeError(f"sample_mm = {sample_mm!r}: give the sample's side in mm, > 0")
    white = manifest.get("white", 1.0)
    if not _positive_finite(white):
        shown = f"{white!r}" if len(repr(white)) < 40 else f"{repr(white)[:20]}…"
        raise InterchangeError(
            f"{folder / MANIFEST}: white = {shown}; expected a finite number > 0"
        )
    if encoding not in (None, *ENCODINGS):
        raise InterchangeError(f"encoding = {encoding!r}: one of {ENCODINGS}")
    if any((folder / name).is_file() for name in ("directions.csv", "directions.toml")):
        listing = list_folder(folder)
        layout, frames, gaps = "folder", listing.frames, ()
        encoding = encoding or listing.encoding
    else:
        ubo = list_ubo2003(folder)
        layout, frames, gaps = "ubo2003", ubo.frames, ubo.gaps
        encoding = encoding or "srgb"
    if not frames:
        raise InterchangeError(f"{folder}: the directions table lists no frames")
    first = _opaque(read_image(frames[0].path), frames[0].path)
    encoding = encoding or ("srgb" if first.dtype == np.uint8 else "linear")
    shape = first.shape
    plan = {
        "name": folder.name,
        "source": {"layout": layout, "folder": str(folder.resolve()), "encoding": encoding,
                   "white": float(white), "gaps": list(gaps)},
        "frames": {"content": "normtexture", "units": "relative radiance",
                   "colour_space": "linear, sRGB primaries" + (
                       " (decoded from sRGB-encoded files)" if encoding == "srgb" else "")},
    }  # fmt: skip
    holder = Holder(sample_mm=float(sample_mm), plate_mm=max(180.0, float(sample_mm) + 40.0))
    rig_config = {"name": f"imported from {layout}", "holder": holder.model_dump()}
    cameras = {NORMTEXTURE_CAMERA: FrameFormat(shape[0], shape[1], shape[2], "float32")}
    archive = Archive.create(out, plan=plan, rig_config=rig_config, cameras=cameras, fsync=False)
    try:
        with archive:
            for index, frame in enumerate(frames):
                image = first if index == 0 else _opaque(read_image(frame.path), frame.path)
                if image.shape != shape or image.dtype != first.dtype:
                    raise InterchangeError(
                        f"{frame.path}: {image.shape[1]}×{image.shape[0]}×{image.shape[2]} "
                        f"{image.dtype} pixels, but {frames[0].path.name} has {shape[1]}×"
                        f"{shape[0]}×{shape[2]} {first.dtype}; every image of a data set has "
                        "one size and pixel type"
                    )
                step = StepRecord(
                    index, "btf", (NORMTEXTURE_CAMERA,), views_deg={NORMTEXTURE_CAMERA:
                    frame.view_deg}, light_deg=frame.light_deg, exposures_s=(1.0,),
                    started_at=time.time(),
                )  # fmt: skip
                archive.append_step(step, {NORMTEXTURE_CAMERA: [_linear(image, encoding, white)]})
                if progress is not None:
                    progress(index + 1, len(frames))
            archive.log_event("imported", source=plan["source"], frames=len(frames))
    except BaseException:
        shutil.rmtree(out, ignore_errors=True)  # the archive this call created, half written
        raise
    views = len({f.view_deg for f in frames})
    lights = len({f.light_deg for f in frames})
    return ImportReport(
        out, layout, len(frames), views, lights, shape, encoding, float(sample_mm), gaps
    )


def _positive_finite(value) -> bool:
    """Whether a manifest's JSON value is a finite number > 0 (an integer of 400
    digits is not: it has no float)."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        return False
    try:
        return math.isfinite(float(value)) and value > 0
    except OverflowError:
        return False


def _opaque(image: np.ndarray, path: Path) -> np.ndarray:
    """``image`` without its alpha channel when that is opaque everywhere (the
    stages take grey or RGB); InterchangeError naming the file otherwise."""
    if image.shape[2] != 4:
        return image
    opaque = np.iinfo(image.dtype).max if image.dtype.kind == "u" else 1.0
    if not np.all(image[:, :, 3] == opaque):
        raise InterchangeError(
            f"{path}: RGBA pixels with a transparent part; a normtexture is grey or RGB "
            "(flatten the images onto a background first)"
        )
    return image[:, :, :3]


def _linear(image: np.ndarray, encoding: str, white: float) -> np.ndarray:
    """float32 linear values of a file's pixels (integers scaled to [0, 1] first),
    converted in bands of rows so that the float64 working copy stays small."""
    linear = np.empty(image.shape, np.float32)
    for top in range(0, image.shape[0], _BAND_ROWS):
        band = image[top : top + _BAND_ROWS]
        if band.dtype.kind == "f":
            values = band
        else:
            values = band / float(np.iinfo(band.dtype).max)
            if encoding == "srgb":
                values = srgb_decode(values)
        linear[top : top + _BAND_ROWS] = values * white
    return linear


def _manifest(folder: Path) -> dict[str, Any]:
    """The manifest of a btfrig export in ``folder``; ``{}`` when there is none."""
    path = folder / MANIFEST
    if not path.is_file():
        return {}
    try:
        manifest = json.loads(path.read_text())
    except ValueError as err:
        raise InterchangeError(f"{path}: not JSON ({err})") from err
    if not isinstance(manifest, dict):
        raise InterchangeError(f"{path}: not a JSON object")
    return manifest
