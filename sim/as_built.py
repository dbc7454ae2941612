"""The simulated rig as built: where it stands off its config, by seeded amounts.

A lab's rig is never built exactly as its config says: a lamp sits a few
millimetres off its place on the arc, one bulb is brighter than another, a
camera's mount is turned a little. A scene's ``[as_built]`` table says by how
much; :meth:`AsBuilt.draw` turns it into one deviation per lamp and camera,
drawn from the table's ``seed``. The simulator renders with them; the rig config
(what ``SimulatedRig.rig_config`` hands the daemon, the archive and processing)
stays the nominal one, so processing sees the rig as a lab's software does, and
only a calibration session can find the deviations.

Each amount bounds a uniform draw: a lamp's position moves by ``u`` mm along each
axis of its mount's frame (the light arc's at arc 0°, where ``rig calibrate
lamps`` reports positions; ``sim.kinds`` turns it with the arc), its intensity is
multiplied by ``1 + u``; a camera moves by ``u`` mm along each axis of its own
frame and turns about each by ``u`` degrees. Each quantity draws from its own
stream, so changing one amount leaves the other deviations as they were.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from rig.camera import PinholeCamera
from rig.config import RigConfig

__all__ = ["AsBuilt", "AsBuiltSpec"]


class AsBuiltSpec(BaseModel):
    """The scene's ``[as_built]`` table: how far the simulated rig stands off its config."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    seed: int = Field(0, ge=0, description="the draws' seed")
    lamp_position_mm: float = Field(
        0.0, ge=0, le=100, description="each lamp moved by up to this along each axis, mm"
    )
    lamp_intensity: float = Field(
        0.0, ge=0, lt=1, description="each lamp's intensity × (1 + u), |u| up to this"
    )
    camera_position_mm: float = Field(
        0.0, ge=0, le=100, description="each camera moved by up to this along each axis, mm"
    )
    camera_rotation_deg: float = Field(
        0.0, ge=0, le=10, description="each camera turned by up to this about each axis, °"
    )

    @property
    def exact(self) -> bool:
        """True when the rig is built exactly to its config (every amount 0)."""
        return not (self.lamp_position_mm or self.lamp_intensity or self.camera_position_mm
                    or self.camera_rotation_deg)  # fmt: skip


@dataclass(frozen=True)
class AsBuilt:
    """One draw of the deviations of a rig's lamps and cameras.

    lamp_offset_mm : lamp id → (3,) float64 mm, in the lamp's mount frame
    lamp_gain : lamp id → its intensity over the config's
    camera_turn : camera id → (3, 3) float64 rotation, camera frame
    camera_shift_mm : camera id → (3,) float64 mm, camera frame
    """

    lamp_offset_mm: dict[str, np.ndarray]
    lamp_gain: dict[str, float]
    camera_turn: dict[str, np.ndarray]
    camera_shift_mm: dict[str, np.ndarray]

    @classmethod
    def draw(cls, spec: AsBuiltSpec, config: RigConfig) -> AsBuilt:
        """The deviations ``spec`` draws for the lamps and cameras of ``config``."""
        lamps = [lamp.id for lamp in config.lamps]
        cameras = [cam.id for cam in config.camera_arc.cameras]

        def uniform(stream: int, bound: float, shape) -> np.ndarray:
            rng = np.random.default_rng(np.random.SeedSequence([spec.seed, stream]))
            return rng.uniform(-bound, bound, shape)

        offsets = uniform(0, spec.lamp_position_mm, (len(lamps), 3))
        gains = 1.0 + uniform(1, spec.lamp_intensity, len(lamps))
        shifts = uniform(2, spec.camera_position_mm, (len(cameras), 3))
        turns = np.deg2rad(uniform(3, spec.camera_rotation_deg, (len(cameras), 3)))
        return cls(
            lamp_offset_mm=dict(zip(lamps, offsets, strict=True)),
            lamp_gain={k: float(g) for k, g in zip(lamps, gains, strict=True)},
            camera_turn={k: cv2.Rodrigues(r)[0] for k, r in zip(cameras, turns, strict=True)},
            camera_shift_mm=dict(zip(cameras, shifts, strict=True)),
        )

    def camera(self, camera_id: str, nominal: PinholeCamera) -> PinholeCamera:
        """``nominal`` moved on its mount: x_cam' = turn · x_cam + shift."""
        turn, shift = self.camera_turn[camera_id], self.camera_shift_mm[camera_id]
        return PinholeCamera(nominal.K, nominal.dist, turn @ nominal.R, turn @ nominal.t + shift,
                             nominal.width, nominal.height)  # fmt: skip
