"""The ``ps`` stage: photometric stereo of every recorded view, on the texel grid.

A *view* is one camera at one turntable angle; its images are the frames of
the ``ps`` steps taken from there, one lamp each. Every frame is registered
onto the sample's N×N texel grid (``processing.registration``: holder markers
→ homography → rectified normtexture), so normals, albedo and height share
the grid of the normtextures and the MDF (``rig.geometry.texel_centers_mm``)
and are in the sample frame. The lamps are near: their positions come from
the archive's rig config and each step's recorded actuators, by the rig's
kind (``RigKind.recorded_lamp_mm``: a Wang rig's arc and turntable angles, a Bonn
lab's plate rotation), and the solve is refined with the
integrated height (seed 004: Woodham's method, then integration). Frames are
linearised by the archive's response curve and divided by the part of their
lamp's flat field the near-lamp model does not explain before they reach the
solver (``processing.offline.radiometry``; ``raw`` keeps them as recorded). A frame
the session flagged as not recording its step's lamp or position, and could not
take again (``StepRecord.excluded``), is left out like an unregistered one.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from processing.offline.radiometry import FrameCorrections, frame_corrections
from processing.offline.runner import View, frame_camera, views_of
from processing.photometric import (
    DistantLights,
    NearLights,
    PixelGrid,
    Reason,
    integrate_normals,
    refine_near,
    solve,
)
from processing.registration import register_capture
from rig.archive import Archive
from rig.config import RigConfig
from rig.geometry import direction_angles, direction_vector
from rig.kinds import rig_kind
from rig.material import PsView, write_ps

__all__ = ["PsStage"]

#: An observation at or above this fraction of full scale counts as clipped.
SATURATION = 0.98


@dataclass(frozen=True)
class PsStage:
    """Photometric stereo per view. ``size``: texels per side; ``method``: the solver's;
    ``raw``: frames as recorded, without the calibration's radiometric corrections;
    ``flat_beyond_mm``: the sample is flat beyond this wavelength, its height keeps no
    longer shape (``processing.photometric.integrate_gradients``; None: as integrated)."""

    size: int = 128
    method: str = "irls"
    refine_iterations: int = 2
    raw: bool = False
    flat_beyond_mm: float | None = 15.0
    name: str = "ps"

    def plan(self, archive: Archive) -> list[View]:
        return views_of(archive, "ps")

    def compute(self, archive_path: str, item: View) -> dict:
        with Archive.open(archive_path, mode="r") as archive:
            config = RigConfig.model_validate(archive.rig_config)
            records = {s.index: s for s in archive.step_table()}
            steps = [records[i] for i in item.steps]
            frames = [archive.read_frame(s.index, item.camera, 0) for s in steps]
            # only K and dist are used: the frame's intrinsics, at the plan's resolution
            lens = frame_camera(archive, config, item.camera, item.turntable_deg)
            corrections = frame_corrections(archive, config, raw=self.raw)
        return self.solve(item, config, lens, steps, frames, corrections=corrections)

    def solve(
        self, item: View, config: RigConfig, lens, steps, frames, *, corrections=None
    ) -> dict:
        """The view's photometric stereo from its frames in memory.

        ``steps``: the view's committed step records; ``frames``: each step's frame of
        ``item.camera`` (sub 0), as archived; ``lens``: the camera of those frames
        (:func:`processing.offline.frame_camera`); ``corrections``: the archive's
        radiometric corrections (:func:`~processing.offline.radiometry.frame_corrections`),
        none when not given. What :meth:`compute` returns.
        """
        corrections = FrameCorrections() if corrections is None else corrections
        full_scale = float(2 ** config.camera(item.camera).bit_depth - 1)
        images, usable, lamps, registered = [], None, [], 0
        for step, frame in zip(steps, frames, strict=True):
            if 0 in step.excluded(item.camera):
                continue  # the rig was not in the step's state (StepRecord.flags): left out
            capture = register_capture(
                frame, config, step, item.camera, size=self.size, camera=lens
            )
            reg = capture.registration
            if not reg.valid:
                continue  # flagged (too few markers…): that lamp is left out, never warped
            registered += 1
            clipped = reg.normtexture.texture >= SATURATION * full_scale
            # near lamps: the solver models cos θ / r², the flat field the rest
            texture, _ = corrections.normtexture(
                frame, reg, step, item.camera, config, lens=lens, size=self.size, lamp_model=True
            )
            # Exposures may differ between lamps: radiance ∝ value / exposure.
            images.append(np.where(clipped, np.inf, texture / step.exposures_s[0]))
            valid = reg.normtexture.valid
            usable = valid if usable is None else usable & valid
            lamps.append(step)
        sample_mm = config.holder.sample_mm
        theta, phi = direction_angles(lens.center)
        view_deg = (float(theta), float(phi))
        if len(images) < 3:
            empty = _empty(item, self.size, registered, len(steps), view_deg)
            return {**empty, "radiometry": corrections.record(cameras=[item.camera], lamps=[])}
        stack = np.stack(images)
        # Clipped observations: one above any real value, so the solver's saturation
        # test drops exactly them.
        finite = stack[np.isfinite(stack)]
        ceiling = float(finite.max()) * 1.01 + 1e-12 if finite.size else 1.0
        stack = np.where(np.isfinite(stack), stack, ceiling).astype(np.float32)
        lights = _lights(config, lamps)
        grid = PixelGrid.for_sample(sample_mm, self.size)
        options = {"method": self.method, "saturation_level": ceiling, "mask": usable}
        if isinstance(lights, NearLights):
            refined = refine_near(
                stack, lights, grid=grid, iterations=self.refine_iterations,
                flat_beyond_mm=self.flat_beyond_mm, **options,
            )  # fmt: skip
            result, height = refined.result, refined.height
        else:
            result = solve(stack, lights, **options)
            height = integrate_normals(
                result.normals, pitch_mm=sample_mm / self.size, mask=result.valid,
                flat_beyond_mm=self.flat_beyond_mm,
            )  # fmt: skip
        return {
            "view": item,
            "normals": result.normals,
            "albedo": result.albedo,
            "valid": result.valid,
            "reason": result.reason,
            "height_mm": height.height_mm,
            "view_deg": view_deg,
            "lamps": [s.lamp for s in lamps],
            "registered": registered,
            "frames": len(steps),
            "radiometry": corrections.record(cameras=[item.camera], lamps=[s.lamp for s in lamps]),
        }

    def write(self, group, archive: Archive, results) -> dict:
        views = [_ps_view(r, self) for r in results]
        write_ps(group, views, attrs={"stage": "ps", "method": self.method})
        solved = sum(int(np.count_nonzero(v.valid)) for v in views)
        texels = len(results) * self.size**2
        return {"views": len(results), "valid_fraction": solved / texels if texels else 0.0}


def _ps_view(result: dict, stage: PsStage) -> PsView:
    view: View = result["view"]
    return PsView(
        view.name, result["normals"], result["albedo"], result["valid"], result["reason"],
        result["height_mm"], view_deg=result["view_deg"],
        attrs={
            "camera": view.camera, "turntable_deg": view.turntable_deg, "steps": list(view.steps),
            "lamps": result["lamps"], "frames": result["frames"],
            "registered": result["registered"], "method": stage.method,
            "flat_beyond_mm": stage.flat_beyond_mm,
            "grid": "rig.geometry.texel_centers_mm",
        },
        radiometry=result["radiometry"],
    )  # fmt: skip


def _lights(config: RigConfig, steps) -> NearLights | DistantLights:
    lamps = [config.lamp(s.lamp) for s in steps]
    intensities = np.array([lamp.intensity for lamp in lamps])
    if all(lamp.kind == "directional" for lamp in lamps):
        directions = np.array([direction_vector(*s.light_deg) for s in steps])
        return DistantLights(directions, intensities)
    rig = rig_kind(config)
    positions = [rig.recorded_lamp_mm(config, s.lamp, s.actuators) for s in steps]
    return NearLights(np.array(positions), intensities)


def _empty(item: View, n: int, registered: int, frames: int, view_deg) -> dict:
    """Fewer than three registered lamps: nothing solvable, every texel flagged."""
    return {
        "view": item,
        "normals": np.broadcast_to(np.array([0, 0, 1], np.float32), (n, n, 3)).copy(),
        "albedo": np.zeros((n, n, 3), np.float32),
        "valid": np.zeros((n, n), bool),
        "reason": np.full((n, n), Reason.TOO_FEW_LIGHTS, np.uint8),
        "height_mm": np.zeros((n, n), np.float32),
        "view_deg": view_deg,
        "lamps": [],
        "registered": registered,
        "frames": frames,
    }
