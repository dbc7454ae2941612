"""Shared small scenes for the MDF tests: the default rig at 1/8 scale (128×96)."""

from __future__ import annotations

from functools import cache

import numpy as np

from processing.mdf import MdfSettings, ReferenceRegion, reconstruct_scan
from processing.mdf.synthetic import RibbedSample, render_scan, rig_scan
from rig.config import default_rig_config
from rig.geometry import texel_centers_mm

CONFIG = default_rig_config()
SAMPLE = RibbedSample()
SCALE = 0.125
STEP_DEG = 0.12
SWEEP_DEG = 11.0
SHEET_SIGMA_MM = 1.5
ARCS = (90.0, 162.0, 234.0, 306.0, 18.0)
TEXELS = 32


@cache
def camera(camera_id: str = "cam2"):
    return CONFIG.camera_model(camera_id).scaled(SCALE)


@cache
def region(camera_id: str = "cam2") -> ReferenceRegion:
    return ReferenceRegion.from_holder(
        camera(camera_id), sample_mm=CONFIG.holder.sample_mm, plate_mm=CONFIG.holder.plate_mm
    )


def grid() -> np.ndarray:
    return texel_centers_mm(CONFIG.holder.sample_mm, TEXELS)


@cache
def scan(arc_deg: float):
    return rig_scan(CONFIG, arc_deg=arc_deg, step_deg=STEP_DEG, sweep_deg=SWEEP_DEG)


@cache
def frames(arc_deg: float, camera_id: str = "cam2", noise_sigma: float = 1.0):
    return tuple(
        render_scan(
            camera(camera_id),
            SAMPLE,
            scan(arc_deg),
            sheet_sigma_mm=SHEET_SIGMA_MM,
            noise_sigma=noise_sigma,
            seed=int(arc_deg),
        )
    )


@cache
def displacement(arc_deg: float, camera_id: str = "cam2", method: str = "gaussian"):
    s = scan(arc_deg)
    return reconstruct_scan(
        frames(arc_deg, camera_id),
        region(camera_id),
        grid(),
        source_mm=s.source_mm,
        sheet_angle_deg=s.angle_deg,
        settings=MdfSettings(peak_method=method),
    )
