"""A standalone material store: a session's material without its frames.

``rig export material ARCHIVE --out M.zarr`` writes a zarr v3 directory whose
root group carries ``format = "btfrig.material"``, ``version``, ``sample_mm``
and ``provenance``, with the archive's ``btf``, ``ps``, ``mdf`` and ``pbr`` groups
copied unchanged below it.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

from rig.archive import Archive, ArchiveError, overlaps_archive, software_versions
from rig.material._errors import MaterialError
from rig.material._material import (
    GROUPS,
    STORE_FORMAT,
    STORE_VERSION,
    archive_provenance,
    read_material,
)

__all__ = ["export_material"]


def export_material(archive_path: str | os.PathLike, out_path: str | os.PathLike) -> Path:
    """Write the material of the session archive ``archive_path`` as a store at ``out_path``.

    The store holds the ``btf``, ``ps``, ``mdf`` and ``pbr`` groups exactly as the
    archive has them, the sample's size, the calibration provenance and the
    software versions (of the archive and of this export); no frames and no
    live previews. The directory appears under its name only when complete.

    Raises
    ------
    MaterialError
        ``out_path`` exists or lies in or around the archive, ``archive_path``
        is not an archive with a readable material, or a group is malformed.
    """
    import zarr

    source, out = Path(archive_path), Path(out_path)
    if overlaps_archive(out, source):
        raise MaterialError(
            f"{out}: lies in or around the archive {source}; give a path outside it for the "
            "material store"
        )
    if out.exists() or out.is_symlink():
        raise MaterialError(f"{out}: already exists; give a new path for the material store")
    try:
        archive = Archive.open(source, mode="r")
    except ArchiveError as err:
        raise MaterialError(f"{source}: not a session archive to export from ({err})") from err
    with archive:
        material = read_material(source)  # every group checked before anything is written
        provenance = archive_provenance(archive)
    provenance["software"]["export"] = software_versions()
    tmp = out.with_name(f".{out.name}.exporting")
    shutil.rmtree(tmp, ignore_errors=True)  # left by a crash during an earlier export
    try:
        root = zarr.open_group(tmp, mode="w", zarr_format=3)
        root.attrs.update(
            format=STORE_FORMAT, version=STORE_VERSION, sample_mm=material.sample_mm,
            size=material.size, provenance=provenance,
        )  # fmt: skip
        for name in GROUPS:
            if (source / "material" / name).is_dir():
                shutil.copytree(source / "material" / name, tmp / name)
        os.rename(tmp, out)
    except OSError as err:
        shutil.rmtree(tmp, ignore_errors=True)
        raise MaterialError(f"{out}: could not write the material store ({err})") from err
    return out
