"""Exporting an archive's recorded frames, raw, as 16-bit PNG, TIFF or OpenEXR files.

Each frame becomes one file ``step{index:05d}_{camera}_{sub}.{png|tif|exr}``;
``manifest.json`` lists each file with its step's kind, view and light
directions, camera, lamp, laser, actuators, exposure and timestamp, and says
how a file's values relate to the archived ones (``value_scale``).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np

from rig.archive import Archive
from rig.interchange._errors import InterchangeError
from rig.interchange._images import write_image
from rig.interchange._manifest import write_manifest

__all__ = ["FRAME_FORMATS", "export_frames"]

#: format → (suffix, what a file holds)
FRAME_FORMATS = {
    "png16": (".png", "16-bit PNG"),
    "tiff": (".tif", "TIFF, the archive's integer type (float frames as 16-bit)"),
    "exr": (".exr", "32-bit float OpenEXR"),
}
#: progress(files done, files in all)
Progress = Callable[[int, int], None]


def _scale(dtype: str, fmt: str) -> tuple[float, str]:
    """File value = archived value × scale, and the file's pixel type."""
    if fmt == "exr":
        return 1.0, "float32"
    if dtype == "uint8" and fmt == "png16":
        return 257.0, "uint16"  # 255 → 65535 exactly
    if dtype == "float32":
        return 65535.0, "uint16"  # linear [0, 1] → full scale (clipped above 1)
    return 1.0, dtype


def export_frames(archive_path, out, fmt: str, *, progress: Progress | None = None) -> Path:
    """Write every committed frame of the archive into the existing empty folder ``out``.

    Returns the manifest's path. The archive is opened read-only.
    """
    if fmt not in FRAME_FORMATS:
        raise InterchangeError(f"format {fmt!r}: one of {sorted(FRAME_FORMATS)}")
    suffix = FRAME_FORMATS[fmt][0]
    out = Path(out)
    files = []
    with Archive.open(archive_path, mode="r") as archive:
        steps = {step.index: step for step in archive.step_table()}
        cameras = {name: f.to_json() for name, f in archive.cameras.items()}
        scales = {name: _scale(f.dtype, fmt) for name, f in archive.cameras.items()}
        table = archive.frame_table()
        for done, row in enumerate(table, start=1):
            step, camera, sub = int(row["step"]), str(row["camera"]), int(row["sub"])
            scale, dtype = scales[camera]
            image = archive.read_frame(step, camera, sub).astype(np.float64) * scale
            if dtype != "float32":
                image = np.round(np.clip(image, 0, np.iinfo(dtype).max))
            name = f"step{step:05d}_{camera}_{sub}{suffix}"
            write_image(out / name, image.astype(dtype))
            record = steps[step]
            files.append({
                "file": name, "step": step, "kind": record.kind, "camera": camera, "sub": sub,
                "exposure_s": float(row["exposure_s"]), "timestamp": float(row["timestamp"]),
                "view_deg": list(record.views_deg.get(camera, ())) or None,
                "light_deg": None if record.light_deg is None else list(record.light_deg),
                "lamp": record.lamp, "laser": record.laser, "actuators": dict(record.actuators),
            })  # fmt: skip
            if progress is not None:
                progress(done, len(table))
        manifest = {
            "format": "btfrig.frames",
            "version": 1,
            "source_archive": str(Path(archive_path).resolve()),
            "file_format": FRAME_FORMATS[fmt][1],
            "cameras": {
                name: {**cameras[name], "file_dtype": scales[name][1],
                       "value_scale": scales[name][0]}
                for name in cameras
            },
            "value_scale_means": "file value = archived value × value_scale (clipped to the "
            "file type's range)",
            "plan": archive.plan,
            "rig_config": archive.rig_config,
            "frames": files,
        }
    return write_manifest(out, manifest)
