"""The ``pbr`` stage: the material's BTF fitted by a glTF PBR material, texel by texel.

Work items are strips of texel rows of the BTF's grid (``material/btf``, written by
the ``btf`` stage, possibly in the same run: the strips are planned without reading
it). Each strip's measured samples are reconstructed from the compressed BTF and
fitted by ``processing.pbr.fit_texels``, starting from the photometric-stereo
normals where the material has them. Values are divided by the BTF's *white* first
(:func:`_white`: the value base colour 1 stands for), recorded with the maps. The
height map comes from the PS maps, else from the MDF's most frontal view, else from
integrating the fitted normals. The layout is ``docs/material.md`` (``rig.material.write_pbr``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from processing.btf import psnr_db
from processing.offline.btf import resample_texels
from processing.offline.runner import StageSkipped
from processing.pbr import FitOptions, btf_samples, fit_texels
from processing.photometric import integrate_normals
from rig.archive import Archive
from rig.interchange import imported_normtextures
from rig.material import PbrMaps, read_material, write_pbr

__all__ = ["PbrStage"]

_COLOURS = ("base_colour", "sheen_colour")
_MAPS = ("base_colour", "roughness", "specular", "specular_colour", "sheen_colour",
         "sheen_roughness", "anisotropy", "anisotropy_deg", "normal")  # fmt: skip


@dataclass(frozen=True)
class PbrStage:
    """Fit of the BTF by a glTF PBR material. ``strips``: work items (row strips of the
    texel grid); ``iterations``: Levenberg–Marquardt iterations per start."""

    strips: int = 16
    iterations: int = 25
    name: str = "pbr"

    def plan(self, archive: Archive) -> list[int]:
        has_btf = "btf" in archive.material or any(s.kind == "btf" for s in archive.step_table())
        return list(range(self.strips)) if has_btf else []

    def compute(self, archive_path: str, item: int) -> dict | None:
        material = read_material(archive_path)
        if material.btf is None:
            return None
        n = material.btf.size
        bounds = np.linspace(0, n, self.strips + 1).round().astype(int)
        rows = slice(int(bounds[item]), int(bounds[item + 1]))
        if rows.start == rows.stop:
            return {"rows": rows, "maps": None, "peak": 0.0}
        samples, light, view, valid = btf_samples(
            material.btf, rows, slot_valid=material.btf_slot_valid
        )
        white = _white(material)
        frontal = material.frontal_ps()
        normal_init = None
        if frontal is not None:
            normals = resample_texels(frontal.normals, n)[rows].reshape(-1, 3)
            normal_init = normals / np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-9)
        saturation = _saturation_of(archive_path)
        options = FitOptions(
            iterations=self.iterations,
            saturation=None if saturation is None else saturation / white,
        )
        result = fit_texels(samples / white, light, view, normal_init=normal_init,
                            sample_valid=valid, options=options)  # fmt: skip
        shape = (rows.stop - rows.start, n)
        maps = {name: getattr(result.params, name).reshape(*shape, -1) for name in _MAPS}
        maps = {name: m[..., 0] if m.shape[-1] == 1 and name not in _COLOURS else m
                for name, m in maps.items()}  # fmt: skip
        maps["error_rmse"] = result.error_rmse.reshape(shape) * np.float32(white)
        maps["flags"] = result.flags.reshape(shape)
        peak = float(np.max(samples[:, valid], initial=0.0))
        return {"rows": rows, "maps": maps, "peak": peak, "options": options, "white": white,
                "saturation": saturation}  # fmt: skip

    def write(self, group, archive: Archive, results) -> dict:
        parts = [r for r in results if r is not None and r["maps"] is not None]
        if not parts:
            raise StageSkipped("the material has no btf to fit; run rig process --stages btf first")
        parts.sort(key=lambda r: r["rows"].start)
        maps = {name: np.concatenate([r["maps"][name] for r in parts]) for name in parts[0]["maps"]}
        material = read_material(archive.path)
        height, source = _height(material, maps["normal"])
        peak = max(r["peak"] for r in parts)
        rmse = float(np.sqrt(np.mean(maps["error_rmse"].astype(np.float64) ** 2)))
        psnr = psnr_db(rmse, peak=max(peak, 1e-12))
        options = parts[0]["options"]
        write_pbr(group, PbrMaps(**maps, height_mm=height, attrs={
            "stage": "pbr", "height_source": source, "psnr_db": psnr, "rmse": rmse, "peak": peak,
            "units": material.btf_units, "white": parts[0]["white"],
            "iterations": options.iterations,
            "saturation": parts[0]["saturation"],
            "roughness_prior": options.roughness_prior,
        }))  # fmt: skip
        flagged = int(np.count_nonzero(maps["flags"]))
        return {"psnr_db": psnr, "rmse": rmse, "flagged_texels": flagged, "height": source}


def _height(material, normals: np.ndarray) -> tuple[np.ndarray, str]:
    """Height (N, N) float32 mm and where it came from: PS, MDF, or the fitted normals."""
    n = normals.shape[0]
    frontal = material.frontal_ps()
    if frontal is not None:
        return resample_texels(frontal.height_mm[..., None], n)[..., 0], "ps"
    if material.mdf is not None:
        view = int(np.argmin(material.mdf.view_dirs_deg[:, 0]))
        distance = material.mdf.distance_mm[view]
        seen = distance >= 0
        if seen.any():
            depth = np.where(seen, distance, np.median(distance[seen]))
            return -resample_texels(depth[..., None], n)[..., 0], "mdf"
    pitch = material.sample_mm / n
    return integrate_normals(normals, pitch_mm=pitch).height_mm.astype(np.float32), "fitted normals"


def _saturation_of(archive_path: str) -> float | None:
    """The linear value at which an imported set's integer codes clipped (98 % of its
    white: the PCA blurs the plateau a little), else None: a captured session's frames
    are flagged when saturated before the BTF is made."""
    with Archive.open(archive_path, mode="r") as archive:
        plan = archive.plan
    if not imported_normtextures(plan):
        return None
    white = plan.get("source", {}).get("white")
    return 0.98 * float(white) if isinstance(white, (int, float)) else None


def _white(material) -> float:
    """The BTF value taken as a white diffuse texel lit frontally (base colour 1): 1 for a
    BTF in relative radiance up to 1, else the 99.9th percentile of value / cos θ_light
    over the most frontal view slot, so that only its brightest 0.1 % would exceed 1."""
    btf = material.btf
    frontal = int(np.argmin(btf.view_dirs_deg[:, 0]))
    cosine = np.maximum(btf.light_vectors[:, 2], 0.2)
    stack = btf.reconstruct_view(frontal) / cosine[:, None, None, None]
    level = float(np.percentile(stack, 99.9))
    return max(level, 1.0) if np.isfinite(level) else 1.0
