"""The ``btf`` stage: registered normtextures of every view slot, compressed by per-view PCA.

The archive's ``btf`` steps are grouped into view slots × lights
(``processing.btf.view_slots``); each slot is one work item: its frames are
registered onto the N×N texel grid (``processing.registration.register_capture``)
and compressed with ``processing.btf.compress_view`` (seed 000 §4.1), so only
one slot's normtextures are in memory at a time. The material layout is
``docs/material.md`` (written by ``rig.material.write_btf``).

A frame whose registration is flagged (too few or collinear markers…), or that
the session flagged as not recording its step's state and could not take again
(``StepRecord.excluded``), is never warped into the data: its slot is stored
empty (``slot_valid`` false) and the reason listed in ``flagged``, so a
re-capture or the renderer's view blending can stand in for it. An imported
archive's frames are normtextures already (``rig import``): registration is
skipped, they are only resampled.
When no slot at all can be registered (a saturated or black session) there
is nothing to compress: the stage is skipped (``StageSkipped``) with the
count of each flag's reason.

A capture the rig made off the pair it was asked for (the Bonn lab's
retro-reflection pairs, ``RigKind.displaced_by_deg``) fills that pair's cell and
is listed in the material's ``displaced`` attribute with the directions it
was measured at (``docs/btf.md``).
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, replace

import numpy as np

from processing.btf import CompressedBTF, SlotTable, compress_view, view_slots
from processing.offline.radiometry import (
    FLAT_FLOOR,
    FrameCorrections,
    calibration_source,
    frame_corrections,
)
from processing.offline.runner import StageSkipped, archive_calibration, frame_camera
from processing.offline.texel_light import (
    IRRADIANCE_FLOOR,
    LampPositions,
    LightResampling,
    lamp_directions,
    lamp_mm,
    lamp_positions,
    light_record,
    per_texel_lights,
    texel_irradiance,
)
from processing.offline.texel_model import model_params, model_record, moved_by_model
from processing.offline.texel_resample import texel_directions
from processing.offline.texel_view import per_texel_views, slot_camera
from processing.registration import FILTERS, rectify, register_capture
from rig.archive import Archive
from rig.config import RigConfig
from rig.interchange import imported_normtextures
from rig.kinds import rig_kind
from rig.material import Radiometry, read_pbr, write_btf

__all__ = [
    "DIRECTIONS", "BtfSlot", "BtfStage", "resample_texels", "slot_normtextures", "slot_table",
]  # fmt: skip

#: ``BtfStage.views`` and ``.lights``: each texel at its slot's nominal direction,
#: resampled from its own, or moved from its own by the fitted reflectance model.
DIRECTIONS = ("nominal", "per texel", "model")


@dataclass(frozen=True)
class BtfSlot:
    """One view slot: its direction and the (step, camera) of each light's capture."""

    index: int
    view_deg: tuple[float, float]
    captures: tuple[tuple[int, str], ...]

    def __str__(self) -> str:
        return f"view slot {self.index} ({self.view_deg[0]:g}°, {self.view_deg[1]:g}°)"


@dataclass(frozen=True)
class BtfStage:
    """Per-view PCA of the registered BTF. ``size``: texels per side; ``components``: c;
    ``raw``: frames as recorded, without the calibration's corrections; ``filter``:
    registration's resampling filter (``processing.registration.FILTERS``);
    ``from_pose``: register every frame from its camera's pose, not its markers;
    ``views``: ``"nominal"`` (the default: each texel keeps its slot's view direction) or
    ``"per texel"`` (each texel resampled from its own view directions onto the slots',
    ``processing.offline.texel_view``; not with ``raw``); ``lights``: ``"per texel"`` (the
    default: the same for each texel's own light directions to the placed lamps,
    ``processing.offline.texel_light``; not with ``raw``) or ``"nominal"``. ``"model"``
    (either): each texel's capture scaled by how much the material's fitted PBR model (the
    ``pbr`` stage's, at this ``size``) changes between the texel's own directions and the
    nominal ones (``processing.offline.texel_model``)."""

    size: int = 128
    components: int = 8
    raw: bool = False
    filter: str = "box"
    from_pose: bool = False
    views: str = "nominal"
    lights: str = "per texel"
    name: str = "btf"

    def __post_init__(self) -> None:
        if self.filter not in FILTERS:
            raise ValueError(f"BtfStage filter = {self.filter!r}: valid are {list(FILTERS)}")
        for option in ("views", "lights"):
            if getattr(self, option) not in DIRECTIONS:
                raise ValueError(f"BtfStage {option} = {getattr(self, option)!r}: valid are "
                                 f"{list(DIRECTIONS)}")  # fmt: skip

    def plan(self, archive: Archive) -> list[BtfSlot]:
        if not any(s.kind == "btf" for s in archive.step_table()):
            return []
        table = slot_table(archive)
        return [
            BtfSlot(j, (float(v[0]), float(v[1])), _captures(table.steps[j], table.cameras[j]))
            for j, v in enumerate(table.view_dirs_deg)
        ]

    def compute(self, archive_path: str, item: BtfSlot) -> dict:
        with Archive.open(archive_path, mode="r") as archive:
            config = RigConfig.model_validate(archive.rig_config)
            corrections = frame_corrections(archive, config, raw=self.raw)
            positions = None if self.raw else _positions(archive, config)
            textures, flagged, counts = slot_normtextures(
                archive, item, size=self.size, corrections=corrections, lamps=positions,
                filter=self.filter, from_pose=self.from_pose,
            )  # fmt: skip
            lamps = [r.lamp for r in archive.step_table() if r.index in dict(item.captures)]
            own_view = self.views != "nominal" and not self.raw
            camera = slot_camera(archive, config, item) if own_view else None
            why_not = self._lights_kept(archive, positions)
            own = None if why_not else _slot_lamps(archive, item, positions)
            model = self._model(archive) if "model" in (self.views, self.lights) else None
            light_deg = None  # the plan's light directions, where the model moves anything
            if model is not None:
                light_deg = own[1] if own is not None else slot_table(archive).light_dirs_deg
        cameras = [c for _, c in item.captures]
        record = _slot_record(corrections.record(cameras=cameras, lamps=lamps), positions)
        result = {"slot": item, "flagged": flagged, "compressed": None, "radiometry": record,
                  "camera": camera, "counts": counts}  # fmt: skip
        if flagged:
            return result
        stack = np.stack(textures).astype(np.float32)
        if why_not:
            result["lights"] = LightResampling(skipped=why_not)
        elif self.lights == "per texel":
            stack, result["lights"] = per_texel_lights(
                stack, *own, sample_mm=config.holder.sample_mm
            )
        if model is not None:
            stack, result["model"] = self._moved(
                stack, item, model, light_deg, lamps=None if own is None else own[0],
                why_not=why_not, camera=camera, sample_mm=config.holder.sample_mm,
            )  # fmt: skip
        return result | {"compressed": compress_view(stack, components=self.components)}

    def _model(self, archive: Archive):
        """The material's fitted PBR model as :func:`model_params`, or why there is none."""
        if self.raw:
            return "--raw"
        try:
            group = archive.material["pbr"]
        except (KeyError, FileNotFoundError):
            return "no fitted PBR model in the material: run the pbr stage first"
        maps = read_pbr(group)
        if maps.size != self.size:
            return (f"the fitted PBR model is {maps.size}² texels, the stage's grid "
                    f"{self.size}²: fit pbr at this size first")  # fmt: skip
        return model_params(maps)

    def _moved(self, stack, item: BtfSlot, model, light_deg, *, lamps, why_not, camera,
               sample_mm: float):  # fmt: skip
        """The slot's normtextures moved by the fitted model (``model``: its parameters, or
        why there are none), and what was done (``ModelMove``, or why not, a string).
        ``lamps``: each capture's lamp (``lamp_mm``), None where not placed (``why_not``)."""
        if isinstance(model, str):
            return stack, model
        n = stack.shape[1]
        own_lights = centre_z = own_view = None
        if self.lights == "model":
            if lamps is None:
                return stack, why_not
            found = lamp_directions(lamps, sample_mm=sample_mm, size=n)
            if isinstance(found, str):
                return stack, found
            own_lights, centre_z = found
        if self.views == "model":
            if camera.centre_mm is None:
                return stack, camera.source
            own_view = texel_directions(camera.centre_mm, sample_mm, n)
        return moved_by_model(stack, model, light_deg=np.asarray(light_deg, np.float64),
                              view_deg=item.view_deg, own_lights=own_lights,
                              centre_z=centre_z, own_view=own_view)  # fmt: skip

    def _lights_kept(self, archive: Archive, lamps: LampPositions | None) -> str | None:
        """Why every texel keeps its captures' light directions, or None: resampled."""
        if self.raw or self.lights == "nominal":
            return "--raw" if self.raw else "lights 'nominal'"
        if imported_normtextures(archive.plan):
            return "imported normtextures: no lamp to place"
        if lamps is None:
            return "no near lamp placed (directional lamps or a Bonn lab)"
        return None

    def write(self, group, archive: Archive, results) -> dict:
        results = sorted(results, key=lambda r: r["slot"].index)
        n_lights = len(results[0]["slot"].captures)
        template = next((r["compressed"] for r in results if r["compressed"] is not None), None)
        if template is None:
            reasons = Counter(f[-1] for r in results for f in r["flagged"])
            raise StageSkipped(
                f"no view slot could be registered, so there is nothing to compress; "
                f"{sum(reasons.values())} frame(s) flagged: "
                + ", ".join(f"{reason} ×{n}" for reason, n in reasons.most_common())
            )
        empty_mean = np.zeros_like(template.mean)
        empty_basis = np.zeros_like(template.basis)
        empty_weights = np.zeros_like(template.weights)
        slots = [r["compressed"] for r in results]
        table = slot_table(archive)
        model = CompressedBTF(
            np.array([r["slot"].view_deg for r in results]),
            table.light_dirs_deg,
            np.stack([s.mean if s else empty_mean for s in slots]),
            np.stack([s.basis if s else empty_basis for s in slots]),
            np.stack([s.weights if s else empty_weights for s in slots]),
            np.stack([s.singular_values if s else np.zeros(n_lights, np.float32) for s in slots]),
            np.array([s.rank if s else 0 for s in slots], np.int32),
        )
        flagged = [f for r in results for f in r["flagged"]]
        radiometry = _merged([r["radiometry"] for r in results])
        radiometry.skipped.update(_texel_flags(sum((r["counts"] for r in results), Counter())))
        radiometry = light_record(radiometry, [r["lights"] for r in results if "lights" in r])
        if "model" in (self.views, self.lights):
            radiometry = model_record(radiometry, [r["model"] for r in results if "model" in r],
                                      lights=self.lights, views=self.views)  # fmt: skip
        if self.raw or self.views == "nominal":
            why = "--raw" if self.raw else "views 'nominal'"
            radiometry = replace(radiometry, skipped=radiometry.skipped | {
                "view": f"{why}: each texel keeps its slot's nominal view"})  # fmt: skip
        elif self.views == "per texel":
            model, radiometry = per_texel_views(
                model, [r["camera"] for r in results], np.array([s is not None for s in slots]),
                radiometry, components=self.components,
                sample_mm=RigConfig.model_validate(archive.rig_config).holder.sample_mm,
            )  # fmt: skip
        write_btf(
            group, model, units=_units(archive, radiometry),
            slot_valid=np.array([s is not None for s in slots]), radiometry=radiometry,
            attrs={"flagged": [list(f) for f in flagged],
                   "flagged_columns": ["slot", "light", "step", "camera", "reason"],
                   "displaced": [[d.slot, d.light, d.step, d.camera, *d.view_deg, *d.light_deg]
                                 for d in table.displaced],
                   "displaced_columns": ["slot", "light", "step", "camera", "view_theta_deg",
                                         "view_phi_deg", "light_theta_deg", "light_phi_deg"]},
        )  # fmt: skip
        return {"slots": len(slots), "flagged_frames": len(flagged),
                "displaced_pairs": len(table.displaced), "components": self.components}  # fmt: skip


def slot_table(archive: Archive, *, gaps: bool = False) -> SlotTable:
    """The archive's BTF captures as view slots × lights (``processing.btf.view_slots``,
    ``gaps`` as there), each step's displacement from its pair asked of the rig's kind."""
    config = RigConfig.model_validate(archive.rig_config)
    rig = rig_kind(config)
    steps = archive.step_table()
    displaced = {
        s.index: rig.displaced_by_deg(config, s.actuators) for s in steps if s.kind == "btf"
    }
    return view_slots(steps, gaps=gaps, displaced_by_deg=displaced)


def slot_normtextures(
    archive: Archive,
    item: BtfSlot,
    *,
    size: int,
    corrections: FrameCorrections | None = None,
    lamps: LampPositions | None = None,
    filter: str = "box",
    from_pose: bool = False,
) -> tuple[list[np.ndarray], list[tuple], Counter]:
    """The (size, size, C) float32 normtextures of a view slot, one per light, in
    relative radiance per second of exposure; the flagged captures; and the flagged
    texel captures: ``"irradiance LAMP"`` → texels the lamp barely lights (divided by
    ``IRRADIANCE_FLOOR``), ``"flat field LAMP"`` → texels its flat field barely lights
    (divided by ``FLAT_FLOOR``), ``"saturated"`` → texels whose footprint touches a pixel
    at the camera's full scale.

    Camera frames are registered onto the texel grid, linearised and divided by
    their lamp's flat field where ``corrections`` (default none) say so, and by
    each texel's near-lamp irradiance over the centre's where ``lamps`` (default
    none) place the lamps (``processing.offline.texel_light``); an
    imported archive's frames already are normtextures
    (``rig.interchange.imported_normtextures``) and are only resampled to
    ``size`` (area averaging). A flagged capture is ``(slot, light, step,
    camera, reason)`` and gives no texture: its registration failed, or the
    session flagged its frame as not recording the step's state
    (``StepRecord.excluded``; reason ``STATE_MISMATCH``).
    """
    corrections = FrameCorrections() if corrections is None else corrections
    records = {s.index: s for s in archive.step_table()}
    textures, flagged, counts = [], [], Counter()
    if imported_normtextures(archive.plan):
        for step, camera in item.captures:
            frame = archive.read_frame(step, camera, 0)
            textures.append(resample_texels(frame, size) / records[step].exposures_s[0])
        return textures, flagged, counts
    config = RigConfig.model_validate(archive.rig_config)
    for light, (step, camera) in enumerate(item.captures):
        record = records[step]
        if 0 in record.excluded(camera):  # the rig was not in the step's state
            flagged.append((item.index, light, step, camera, "STATE_MISMATCH"))
            continue
        frame = archive.read_frame(step, camera, 0)
        # the lens (intrinsics, distortion) matters, not the pose: the markers give it
        # (a rig without a turntable, as the Bonn lab, records none)
        turntable = record.actuators.get("turntable_deg", 0.0)
        lens = frame_camera(archive, config, camera, turntable)
        reg = register_capture(
            frame, config, record, camera, size=size, camera=lens, filter=filter,
            from_pose=from_pose,
        ).registration  # fmt: skip
        if not reg.valid:
            flagged.append((item.index, light, step, camera, reg.reason.name))
            continue
        # with the lamps placed, the flat field divides out only what 1/r² does not explain
        texture, dim = corrections.normtexture(
            frame, reg, record, camera, config, lens=lens, size=size,
            lamp_model=lamps is not None, filter=filter,
        )  # fmt: skip
        if dim.any():
            counts[f"flat field {record.lamp}"] += int(dim.sum())
        counts["saturated"] += _clipped_texels(frame, reg, config, camera, lens, size, filter)
        if lamps is not None:
            ratio, floored = texel_irradiance(
                lamps, config, record.lamp, sample_mm=config.holder.sample_mm, size=size,
                arc_deg=record.actuators.get("arc_deg", 0.0), turntable_deg=turntable,
            )  # fmt: skip
            texture = texture / ratio[..., None]
            if floored.any():
                counts[f"irradiance {record.lamp}"] += int(floored.sum())
        textures.append((texture / record.exposures_s[0]).astype(np.float32))
    return textures, flagged, counts


def _slot_lamps(archive: Archive, item: BtfSlot, lamps: LampPositions):
    """What ``per_texel_lights`` needs of a slot besides its normtextures: each capture's
    lamp (``lamp_mm``, (3,) mm or None) and the plan's (L, 2) light directions."""
    records = {r.index: r for r in archive.step_table()}
    sources = [lamp_mm(
        lamps, records[step].lamp, arc_deg=records[step].actuators.get("arc_deg", 0.0),
        turntable_deg=records[step].actuators.get("turntable_deg", 0.0),
    ) for step, _ in item.captures]  # fmt: skip
    return sources, slot_table(archive).light_dirs_deg


def _clipped_texels(frame, reg, config: RigConfig, camera: str, lens, size: int, filter) -> int:
    """Texels whose footprint touches a pixel at full scale in any channel."""
    clipped = np.asarray(frame) >= 2 ** config.camera(camera).bit_depth - 1
    if not clipped.any():
        return 0
    mask = clipped if clipped.ndim == 2 else clipped.any(axis=2)
    touched = rectify(mask.astype(np.float32), reg.homography, sample_mm=config.holder.sample_mm,
                      size=size, camera=lens, filter=filter).texture[..., 0] > 0  # fmt: skip
    return int(touched.sum())


def _positions(archive: Archive, config: RigConfig) -> LampPositions | None:
    calibration = archive_calibration(archive)
    source = "" if calibration is None else calibration_source(calibration, "lamps")
    return lamp_positions(config, calibration, source)


def _slot_record(record: Radiometry, lamps: LampPositions | None) -> Radiometry:
    """The slot's record with the per-texel irradiance correction: its source, or why not."""
    if lamps is None:
        skipped = record.skipped | {"irradiance": (
            "no near lamp placed (directional lamps, a Bonn lab or --raw): the centre's "
            "irradiance for every texel")}  # fmt: skip
        return replace(record, skipped=skipped)
    return replace(record, sources=record.sources | {"irradiance": lamps.source})


def _texel_flags(counts: Counter) -> dict[str, str]:
    """The record's notes on the flagged texel captures of every slot
    (``counts``: :func:`slot_normtextures`'s, summed over the slots)."""
    notes = {}
    for key, count in sorted(counts.items()):
        if key == "saturated" and count:
            notes[key] = (f"{count} texel captures touch clipped pixels: stored as clipped "
                          "(a lower bound of their radiance)")  # fmt: skip
        elif key.startswith("flat field ") and count:
            notes[key] = (f"{count} texel captures its flat field barely lights (under "
                          f"{FLAT_FLOOR:g} of the centre's): divided by that floor")  # fmt: skip
        elif key.startswith("irradiance ") and count:
            notes[key] = (
                f"{count} texel captures it barely lights (outside its cone, or the lamp at or "
                f"below the sample's plane): divided by the floor, {IRRADIANCE_FLOOR:g} of the "
                "centre's irradiance"
            )
    return notes


def _merged(records: list[Radiometry]) -> Radiometry:
    """One record for the whole BTF from each slot's."""
    first = records[0]
    return Radiometry(
        tuple(sorted({c for r in records for c in r.linearised})),
        tuple(sorted({x for r in records for x in r.flat_fielded})),
        first.calibration_version, first.sources,
        {k: v for r in records for k, v in r.skipped.items()},
    )  # fmt: skip


def _units(archive: Archive, radiometry: Radiometry) -> str:
    if imported_normtextures(archive.plan):
        return f"{archive.plan['frames']['units']} ({archive.plan['frames']['colour_space']})"
    if radiometry.linearised:
        values = "linear relative exposure (1 at camera value 128)"
    else:
        values = "camera value over full scale (as recorded, not linearised)"
    flat = ", lamp fall-off divided out" if radiometry.flat_fielded else ""
    near = ", near-lamp irradiance per texel divided out"
    near = near if "irradiance" in radiometry.sources else ""
    return f"{values} per second of exposure{flat}{near}"


def resample_texels(frame: np.ndarray, size: int) -> np.ndarray:
    """A normtexture frame on the size × size texel grid: area average when it shrinks,
    linear interpolation when it grows."""
    import cv2

    height, width = frame.shape[:2]
    if (height, width) == (size, size):
        return frame.astype(np.float32)
    shrink = size <= min(height, width)
    resized = cv2.resize(frame.astype(np.float32), (size, size),
                         interpolation=cv2.INTER_AREA if shrink else cv2.INTER_LINEAR)  # fmt: skip
    return resized.reshape(size, size, frame.shape[2])


def _captures(steps, cameras) -> tuple[tuple[int, str], ...]:
    return tuple((int(s), str(c)) for s, c in zip(steps, cameras, strict=True))
