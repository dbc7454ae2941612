"""The ``btf`` stage: registered normtextures of every view slot, compressed by per-view PCA.

The archive's ``btf`` steps are grouped into view slots × lights
(``processing.btf.view_slots``); each slot is one work item: its frames are
registered onto the N×N texel grid (``processing.registration.register_capture``)
and compressed with ``processing.btf.compress_view`` (seed 000 §4.1), so only
one slot's normtextures are in memory at a time. The material layout is
``docs/material.md`` (written by ``rig.material.write_btf``).

A frame whose registration is flagged (too few or collinear markers…) is never
warped into the data: its slot is stored empty (``slot_valid`` false) and the
reason listed in ``flagged``, so a re-capture or the renderer's view blending
can stand in for it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from processing.btf import CompressedBTF, compress_view, view_slots
from processing.offline.runner import frame_camera
from processing.registration import register_capture
from rig.archive import Archive
from rig.config import RigConfig
from rig.material import write_btf

__all__ = ["BtfSlot", "BtfStage"]


@dataclass(frozen=True)
class BtfSlot:
    """One view slot: its direction and the (step, camera) of each light's capture."""

    index: int
    view_deg: tuple[float, float]
    captures: tuple[tuple[int, str], ...]


@dataclass(frozen=True)
class BtfStage:
    """Per-view PCA of the registered BTF. ``size``: texels per side; ``components``: c."""

    size: int = 128
    components: int = 8
    name: str = "btf"

    def plan(self, archive: Archive) -> list[BtfSlot]:
        if not any(s.kind == "btf" for s in archive.step_table()):
            return []
        table = view_slots(archive.step_table())
        return [
            BtfSlot(j, (float(v[0]), float(v[1])), _captures(table.steps[j], table.cameras[j]))
            for j, v in enumerate(table.view_dirs_deg)
        ]

    def compute(self, archive_path: str, item: BtfSlot) -> dict:
        with Archive.open(archive_path, mode="r") as archive:
            config = RigConfig.model_validate(archive.rig_config)
            records = {s.index: s for s in archive.step_table()}
            textures, flagged = [], []
            for light, (step, camera) in enumerate(item.captures):
                record = records[step]
                frame = archive.read_frame(step, camera, 0)
                turntable = record.actuators["turntable_deg"]
                lens = frame_camera(archive, config, camera, turntable)
                reg = register_capture(
                    frame, config, record, camera, size=self.size, camera=lens
                ).registration
                if not reg.valid:
                    flagged.append((item.index, light, step, camera, reg.reason.name))
                    continue
                full_scale = float(2 ** config.camera(camera).bit_depth - 1)
                textures.append(reg.normtexture.texture / (full_scale * record.exposures_s[0]))
        if flagged:
            return {"slot": item, "flagged": flagged, "compressed": None}
        stack = np.stack(textures).astype(np.float32)
        slot = compress_view(stack, components=self.components)
        return {"slot": item, "flagged": [], "compressed": slot}

    def write(self, group, archive: Archive, results) -> dict:
        results = sorted(results, key=lambda r: r["slot"].index)
        n_lights = len(results[0]["slot"].captures)
        template = next((r["compressed"] for r in results if r["compressed"] is not None), None)
        if template is None:
            raise ValueError("btf: no view slot could be registered; nothing to compress")
        empty_mean = np.zeros_like(template.mean)
        empty_basis = np.zeros_like(template.basis)
        empty_weights = np.zeros_like(template.weights)
        slots = [r["compressed"] for r in results]
        model = CompressedBTF(
            np.array([r["slot"].view_deg for r in results]),
            view_slots(archive.step_table()).light_dirs_deg,
            np.stack([s.mean if s else empty_mean for s in slots]),
            np.stack([s.basis if s else empty_basis for s in slots]),
            np.stack([s.weights if s else empty_weights for s in slots]),
            np.stack([s.singular_values if s else np.zeros(n_lights, np.float32) for s in slots]),
            np.array([s.rank if s else 0 for s in slots], np.int32),
        )
        flagged = [f for r in results for f in r["flagged"]]
        write_btf(
            group, model, units="relative radiance per second of exposure",
            slot_valid=np.array([s is not None for s in slots]),
            attrs={"flagged": [list(f) for f in flagged],
                   "flagged_columns": ["slot", "light", "step", "camera", "reason"]},
        )  # fmt: skip
        return {"slots": len(slots), "flagged_frames": len(flagged), "components": self.components}


def _captures(steps, cameras) -> tuple[tuple[int, str], ...]:
    return tuple((int(s), str(c)) for s, c in zip(steps, cameras, strict=True))
