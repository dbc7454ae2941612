"""What the exports of normtextures and maps read from an archive.

The normtextures of a UBO2003 export come from one of three places: an
imported archive's frames (already rectified), a captured session's frames
registered onto the texel grid (``processing.offline.btf.slot_normtextures``),
or the compressed BTF of ``material/btf`` (``processing.btf.reconstruct``).
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from rig.errors import ConfigError

__all__ = ["BtfSource", "btf_source", "pbr_maps", "ps_maps"]


@dataclass(frozen=True)
class BtfSource:
    """Directions of the view slots and lights, and the normtexture of each pair
    (``normtexture(view, light)``: (N, N, C) linear, or None for a gap); ``white``:
    the linear value an import recorded as its files' full scale, else None."""

    views_deg: np.ndarray
    lights_deg: np.ndarray
    normtexture: Callable[[int, int], np.ndarray | None]
    manifest: dict[str, Any]
    white: float | None = None

    def auto_white(self) -> float:
        """The import's white, else the 99.9th percentile of the most frontal view
        slot under every light (what the 8-bit files then clip is the brightest 0.1 %
        of that slot), else 1."""
        if self.white is not None:
            return self.white
        frontal = int(np.argmin(self.views_deg[:, 0]))
        textures = [self.normtexture(frontal, i) for i in range(len(self.lights_deg))]
        values = [t for t in textures if t is not None]
        level = float(np.percentile(np.stack(values), 99.9)) if values else 0.0
        return level if np.isfinite(level) and level > 0 else 1.0


@contextlib.contextmanager
def btf_source(archive_path: Path, *, from_material: bool, size: int) -> Iterator[BtfSource]:
    """The normtextures of an archive, with it open read-only while the block runs."""
    from processing.btf import reconstruct
    from processing.offline.btf import BtfSlot, slot_normtextures, slot_table
    from rig.archive import Archive
    from rig.config import Holder
    from rig.interchange import NORMTEXTURE_CAMERA, imported_normtextures
    from rig.material import CompressedBTF, read_material

    manifest: dict[str, Any] = {"source_archive": str(archive_path.resolve())}
    if from_material:
        material = read_material(archive_path)
        if not isinstance(material.btf, CompressedBTF):
            has = "a global SVD" if material.btf is not None else "no btf"
            raise ConfigError(
                f"{archive_path}: its material has {has}; --from-material needs the per-view "
                "PCA of `rig process --stages btf`"
            )
        model, valid = material.btf, material.btf_slot_valid

        def reconstructed(view: int, light: int) -> np.ndarray | None:
            return reconstruct(model, view=view, light=light) if valid[view] else None

        manifest.update(
            content="PCA reconstruction of material/btf", units=material.btf_units,
            sample_mm=material.sample_mm,
        )  # fmt: skip
        yield BtfSource(model.view_dirs_deg, model.light_dirs_deg, reconstructed, manifest)
        return
    with Archive.open(archive_path, mode="r") as archive:
        holder = Holder.model_validate(archive.rig_config.get("holder", {}))
        manifest["sample_mm"] = holder.sample_mm
        table = slot_table(archive, gaps=True)
        imported = imported_normtextures(archive.plan)
        if imported:
            size = archive.cameras[NORMTEXTURE_CAMERA].height
        cache: dict[int, dict[int, np.ndarray]] = {}

        def normtexture(view: int, light: int) -> np.ndarray | None:
            if view not in cache:
                cache.clear()  # one slot in memory at a time
                lights = [i for i, step in enumerate(table.steps[view]) if step >= 0]
                captures = tuple((int(table.steps[view, i]), str(table.cameras[view, i]))
                                 for i in lights)  # fmt: skip
                slot = BtfSlot(view, tuple(table.view_dirs_deg[view]), captures)
                textures, flagged, _ = slot_normtextures(archive, slot, size=size)
                lost = {f[1] for f in flagged}  # positions in captures
                kept = iter(textures)
                cache[view] = {i: next(kept) for k, i in enumerate(lights) if k not in lost}
            return cache[view].get(light)

        manifest.update(
            content="imported normtextures" if imported else f"frames registered onto {size}²",
            units="relative radiance" + ("" if imported else " per second of exposure"),
        )
        white = float(archive.plan["source"]["white"]) if imported else None
        yield BtfSource(table.view_dirs_deg, table.light_dirs_deg, normtexture, manifest, white)


def ps_maps(archive_path: Path, view_name: str | None):
    """The encoded maps of a PS view (the most frontal by default), the sample's
    side in mm, and the start of the export's manifest."""
    from rig.interchange import texture_maps
    from rig.material import read_material

    material = read_material(archive_path)
    if not material.ps:
        raise ConfigError(
            f"{archive_path}: its material has no ps maps; run `rig process --stages ps` first"
        )
    if view_name is None:
        view = material.frontal_ps()
    elif view_name in material.ps:
        view = material.ps[view_name]
    else:
        raise ConfigError(
            f"--view {view_name!r}: not a PS view; the views are {sorted(material.ps)}"
        )
    manifest = {
        "source_archive": str(Path(archive_path).resolve()),
        "view": view.name,
        "view_deg": None if view.view_deg is None else list(view.view_deg),
    }
    return texture_maps(view), material.sample_mm, manifest


def pbr_maps(archive_path: Path):
    """The material's fitted PBR maps, the sample's side in mm, and the start of the
    export's manifest: the source and the fit's error against the BTF."""
    from rig.material import read_material

    material = read_material(archive_path)
    if material.pbr is None:
        raise ConfigError(
            f"{archive_path}: its material has no PBR fit; run `rig process --stages pbr` first"
        )
    attrs = material.pbr.attrs
    manifest = {
        "source_archive": str(Path(archive_path).resolve()),
        "model": "glTF metallic-roughness + KHR_materials_specular, _sheen, _anisotropy",
        "fit": {
            "psnr_db": attrs.get("psnr_db"), "rmse": attrs.get("rmse"), "peak": attrs.get("peak"),
            "units": attrs.get("units"), "white": attrs.get("white"),
            "flagged_texels": int(np.count_nonzero(material.pbr.flags)),
            "texels": int(material.pbr.flags.size), "height_source": attrs.get("height_source"),
        },
        "sample_mm": material.sample_mm,
    }  # fmt: skip
    return material.pbr, material.sample_mm, manifest
