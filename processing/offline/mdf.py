"""The ``mdf`` stage: the mesostructure distance function of every recorded view.

A *view* is one camera at one turntable angle; its scans are the ``mdf`` steps
taken from there, one laser location each (seed 001 §3). Per scan, the frames
and the sheet tilt read back at each frame (the step's ``scan`` event) give
D_{v,l} on the texel grid (``processing.mdf.reconstruct_scan``: line in the
reference region, space-time peaks, triangulation), less the frames the step
still flags as not recording their planned tilt (``StepRecord.excluded``; a
frame taken again at its tilt counts); the scans of a view are
merged with the tetrahedron weights (``merge_scans``). The laser sheet's angle
to the reference plane comes from the rig's kinematics at each recorded tilt
(``rig.kinematics.laser_plane``), shifted by what the archive's laser
calibration (``rig calibrate laser``) measured against the model, if it has one.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from processing.mdf import (
    MdfSettings,
    ReferenceRegion,
    assemble_mdf,
    merge_scans,
    reconstruct_scan,
    view_direction_deg,
)
from processing.offline.runner import View, archive_calibration, frame_camera, views_of
from rig.archive import Archive
from rig.config import RigConfig
from rig.geometry import texel_centers_mm
from rig.kinematics import laser_plane, laser_source_mm
from rig.material import write_mdf

__all__ = ["MdfStage"]


@dataclass(frozen=True)
class MdfStage:
    """MDF per view on the N×N texel grid; ``peak``: the sub-pixel peak detector."""

    size: int = 128
    peak: str = "gaussian"
    name: str = "mdf"

    def plan(self, archive: Archive) -> list[View]:
        return views_of(archive, "mdf")

    def compute(self, archive_path: str, item: View) -> dict:
        with Archive.open(archive_path, mode="r") as archive:
            config = RigConfig.model_validate(archive.rig_config)
            records = {s.index: s for s in archive.step_table()}
            tilts = {e.payload["step"]: e.payload["tilts_deg"] for e in archive.events("scan")}
            holder = config.holder
            first = records[item.steps[0]]
            camera = frame_camera(archive, config, item.camera, first.actuators["turntable_deg"])
            region = ReferenceRegion.from_holder(
                camera, sample_mm=holder.sample_mm, plate_mm=holder.plate_mm
            )
            texels = texel_centers_mm(holder.sample_mm, self.size)
            settings = MdfSettings(peak_method=self.peak)
            scans = []
            for index in item.steps:
                record = records[index]
                arc, turntable = record.actuators["arc_deg"], record.actuators["turntable_deg"]
                correction = _calibrated_offset_deg(archive, config, record.laser, arc, turntable)
                angles = [
                    _sheet_angle_deg(config, arc, record.laser, tilt, turntable) + correction
                    for tilt in tilts[index]
                ]
                source_mm = laser_source_mm(
                    config, record.laser, arc_deg=arc, turntable_deg=turntable
                )
                # A frame still flagged did not record its tilt: it is left out.
                left_out = record.excluded(item.camera)
                subs = [sub for sub in range(len(angles)) if sub not in left_out]
                frames = (archive.read_frame(index, item.camera, sub) for sub in subs)
                scan = reconstruct_scan(
                    frames, region, texels, source_mm=source_mm,
                    sheet_angle_deg=np.array([angles[sub] for sub in subs]), settings=settings,
                )  # fmt: skip
                scans.append(scan)
        merged = merge_scans(scans)
        return {"view": item, "merged": merged, "view_deg": view_direction_deg(camera)}

    def write(self, group, archive: Archive, results) -> dict:
        results = sorted(results, key=lambda r: r["view"].name)
        mdf = assemble_mdf([r["merged"] for r in results], [r["view_deg"] for r in results])
        attrs = {
            "stage": "mdf", "peak": self.peak, "views": [r["view"].name for r in results],
            "grid": "rig.geometry.texel_centers_mm",
        }  # fmt: skip
        write_mdf(group, replace(mdf, attrs=attrs))
        seen = float(np.mean(mdf.distance_mm >= 0))
        return {"views": len(results), "seen_fraction": seen}


def _sheet_angle_deg(config: RigConfig, arc: float, mount: int, tilt: float, turntable: float):
    normal, _ = laser_plane(
        config, arc_deg=arc, mount=mount, tilt_deg=tilt, turntable_deg=turntable
    )
    return float(np.degrees(np.arccos(np.clip(normal[2], -1.0, 1.0))))


def _calibrated_offset_deg(archive: Archive, config: RigConfig, mount: int, arc, turntable):
    """What the archive's laser calibration adds to the kinematic sheet angle of
    ``mount`` (0 without one): measured minus modelled, at the calibrated tilt."""
    calibration = archive_calibration(archive)
    measured = None if calibration is None else calibration.laser.get(f"mount{mount}")
    if measured is None:
        return 0.0
    modelled = _sheet_angle_deg(config, arc, mount, measured.tilt_deg, turntable)
    angle = min(measured.angle_deg, 180.0 - measured.angle_deg)  # to the plane, ≤ 90°
    return angle - modelled
