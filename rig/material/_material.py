"""A material as one object: what a session measured, read from an archive or a
standalone material store (``docs/material.md``)."""

from __future__ import annotations

import contextlib
import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from rig.archive import Archive
from rig.calfile import CalibrationFile
from rig.config import Holder, RigConfig
from rig.errors import ConfigError, RigError
from rig.geometry import direction_angles
from rig.material._btf import read_btf
from rig.material._btf_model import CompressedBTF, GlobalSVD
from rig.material._errors import MaterialError
from rig.material._mdf import Mdf, read_mdf
from rig.material._pbr import PbrMaps, read_pbr
from rig.material._ps import PsView, read_ps
from rig.material._radiometry import Radiometry

__all__ = [
    "GROUPS",
    "STORE_FORMAT",
    "STORE_VERSION",
    "Material",
    "archive_provenance",
    "read_material",
]

#: ``format`` of a standalone material store's root group
STORE_FORMAT = "btfrig.material"
STORE_VERSION = 1
#: the groups that make a material (``live`` holds per-frame previews, not the material)
GROUPS = ("btf", "ps", "mdf", "pbr")


@dataclass(frozen=True)
class Material:
    """The measured material: compressed BTF, photometric-stereo maps, MDF and PBR fit.

    Attributes
    ----------
    source : Path
        The archive or standalone store it was read from.
    sample_mm : float
        Side of the square sample area the texel grids cover, mm.
    size : int
        N of the BTF's texel grid, else of the PS maps, else of the MDF (each
        part keeps its own arrays' N; all cover the same ``sample_mm``).
    btf : CompressedBTF, GlobalSVD or None
    btf_slot_valid : (n_views,) bool or None
        False for view slots stored empty; all True when the store does not say.
    btf_units : str or None
        What the BTF's texel values measure.
    btf_radiometry : Radiometry or None
        The radiometric corrections its frames had (each PS view has its own).
    ps : dict[str, PsView]
        Photometric-stereo maps per view (empty when none).
    mdf : Mdf or None
    pbr : PbrMaps or None
        The BTF's fitted glTF PBR maps (``rig process --stages pbr``).
    provenance : dict
        ``source_archive``, ``calibration_version``, ``calibration`` (each
        calibrated section's provenance), ``corrections`` (the calibrated
        results processing applies: camera models, laser mounts), ``results``
        (when each group was written), ``software`` (versions).
    """

    source: Path
    sample_mm: float
    size: int
    btf: CompressedBTF | GlobalSVD | None = None
    btf_slot_valid: np.ndarray | None = None
    btf_units: str | None = None
    btf_radiometry: Radiometry | None = None
    ps: dict[str, PsView] = field(default_factory=dict)
    mdf: Mdf | None = None
    pbr: PbrMaps | None = None
    provenance: dict[str, Any] = field(default_factory=dict)

    def frontal_ps(self) -> PsView | None:
        """The PS view seen most nearly from above (smallest view θ), or the only one.

        Views that do not record their direction come after those that do;
        None when there are no PS maps.
        """
        if not self.ps:
            return None
        return min(
            self.ps.values(),
            key=lambda v: (v.view_deg is None, v.view_deg[0] if v.view_deg else 0.0, v.name),
        )


def read_material(path: str | os.PathLike) -> Material:
    """The material of a session archive (its ``material/`` group) or of a standalone store.

    Raises
    ------
    MaterialError
        ``path`` is neither, a group is malformed or of an unknown version, or
        the material has none of btf, ps and mdf.
    """
    import zarr

    path = Path(path)
    attrs = _root_attributes(path)
    if attrs.get("format") == STORE_FORMAT:
        if attrs.get("version") != STORE_VERSION:
            raise MaterialError(
                f"{path}: material store version {attrs.get('version')!r}; "
                f"this btfrig reads version {STORE_VERSION}"
            )
        sample_mm = attrs.get("sample_mm")
        if not isinstance(sample_mm, (int, float)) or not sample_mm > 0:
            raise MaterialError(f"{path}: attribute sample_mm = {sample_mm!r}; expected mm > 0")
        root = zarr.open_group(path, mode="r")
        provenance = dict(attrs.get("provenance", {}))
        return _material(path, root, float(sample_mm), provenance, where=str(path))
    if "btfrig_archive" in attrs:
        with Archive.open(path, mode="r") as archive:
            holder, config = _holder_and_config(archive)
            return _material(
                path, archive.material, holder.sample_mm, archive_provenance(archive),
                where=f"{path}/material", config=config,
            )  # fmt: skip
    raise MaterialError(
        f"{path}: neither a session archive nor a material store (its zarr.json has no "
        f"'btfrig_archive' attribute and no format {STORE_FORMAT!r})"
    )


def archive_provenance(archive: Archive) -> dict[str, Any]:
    """What a material from ``archive`` owes to it (``provenance`` of :class:`Material`)."""
    calibration = archive.calibration
    _, config = _holder_and_config(archive)
    if calibration and config is not None:  # what processing can use of it
        source = f"{archive.path} (calibration v{archive.calibration_version})"
        with contextlib.suppress(ConfigError):  # as stored, where it no longer validates
            fitted, _ = CalibrationFile.from_dict(calibration, source=source).fitted_to(config)
            fits = {} if fitted is None else fitted.model_dump(mode="json", exclude_none=True)
            calibration = fits
    sections = {
        key.removesuffix("_provenance"): value
        for key, value in calibration.items()
        if key.endswith("_provenance")
    }
    results = {e.payload["name"]: e.time for e in archive.events("material")}
    return {
        "source_archive": str(Path(archive.path).resolve()),
        "calibration_version": archive.calibration_version,
        "calibration": sections,
        "corrections": {
            "cameras": sorted(calibration.get("cameras", {})),
            "laser": sorted(calibration.get("laser", {})),
        },
        "results": {name: time for name, time in results.items() if name in GROUPS},
        "software": {"archive": archive.software},
    }


def _root_attributes(path: Path) -> dict[str, Any]:
    document = path / "zarr.json"
    if not document.is_file():
        raise MaterialError(
            f"{path}: no zarr.json here; expected a session archive or a material store "
            "(rig export material ARCHIVE --out M.zarr)"
        )
    try:
        return dict(json.loads(document.read_text()).get("attributes", {}))
    except (ValueError, AttributeError) as err:
        raise MaterialError(f"{document}: not a readable zarr v3 group document ({err})") from err


def _holder_and_config(archive: Archive) -> tuple[Holder, RigConfig | None]:
    """The archive's sample holder and rig config (None when the stored config no
    longer validates: the holder alone then gives the sample's size)."""
    stored = archive.rig_config
    try:
        config = RigConfig.model_validate(stored)
    except ValueError:
        try:
            return Holder.model_validate(stored.get("holder", {})), None
        except ValueError as err:
            raise MaterialError(
                f"{archive.path}: rig config holder = {stored.get('holder')!r} gives no "
                "sample size; expected holder.sample_mm > 0 (mm)"
            ) from err
    return config.holder, config


def _material(
    path: Path,
    root,
    sample_mm: float,
    provenance: dict,
    *,
    where: str,
    config: RigConfig | None = None,
) -> Material:
    parts: dict[str, Any] = {}
    for name in GROUPS:
        if name not in root:
            continue
        group = root[name]
        if not hasattr(group, "groups"):
            raise MaterialError(f"{where}/{name}: is an array; expected the {name} group")
        parts[name] = group
    if not parts:
        raise MaterialError(
            f"{where}: holds none of {', '.join(GROUPS)}; run `rig process` on the archive "
            "(e.g. --stages ps,mdf,btf) first"
        )
    btf = read_btf(parts["btf"], where=f"{where}/btf") if "btf" in parts else None
    ps = read_ps(parts["ps"], where=f"{where}/ps") if "ps" in parts else {}
    if config is not None:
        ps = {name: _with_view(view, config) for name, view in ps.items()}
    mdf = read_mdf(parts["mdf"], where=f"{where}/mdf") if "mdf" in parts else None
    pbr = read_pbr(parts["pbr"], where=f"{where}/pbr") if "pbr" in parts else None
    if btf is not None:
        size = btf.model.size
    elif ps:
        size = next(iter(ps.values())).size
    elif mdf is not None:
        size = mdf.size
    else:
        size = pbr.size
    return Material(
        source=path, sample_mm=float(sample_mm), size=int(size),
        btf=None if btf is None else btf.model,
        btf_slot_valid=None if btf is None else btf.slot_valid,
        btf_units=None if btf is None else btf.units,
        btf_radiometry=None if btf is None else btf.radiometry,
        ps=ps, mdf=mdf, pbr=pbr, provenance=provenance,
    )  # fmt: skip


def _with_view(view: PsView, config: RigConfig) -> PsView:
    """A version-0 view gets its direction from the rig config's nominal camera."""
    camera, turntable = view.attrs.get("camera"), view.attrs.get("turntable_deg")
    if view.view_deg is not None or camera is None or turntable is None:
        return view
    try:
        model = config.camera_model(camera, turntable_deg=float(turntable))
    except RigError:
        return view  # a camera the config no longer has: the direction stays unknown
    theta, phi = direction_angles(model.center)
    return PsView(
        view.name, view.normals, view.albedo, view.valid, view.reason, view.height_mm,
        view_deg=(float(theta), float(phi)), attrs=view.attrs, radiometry=view.radiometry,
    )  # fmt: skip
