"""The calibration file: what ``rig calibrate`` measured, with its residuals.

A TOML file a rig config names in ``calibration``; the daemon copies it into
every session archive it records (``Archive.calibration``), and processing
reads it from there, so an archive keeps the calibration it was taken with and
re-processing can be given a newer one (``rig calibrate … --apply ARCHIVE``).

One section per target; calibrating one target replaces its section and keeps
the others. Every section says when and from which archive it was measured.
Units: pixels, mm, degrees. Camera poses map world to camera:
``x_cam = R · x_world + t`` (turntable at 0°).
"""

from __future__ import annotations

from datetime import UTC, datetime
from pathlib import Path

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from rig.camera import PinholeCamera
from rig.config import RigConfig
from rig.errors import ConfigError
from rig.tomlfile import format_validation_error, read_toml, write_toml

__all__ = [
    "FORMAT_VERSION",
    "CalibrationFile",
    "CameraResult",
    "LampResult",
    "LaserResult",
    "Provenance",
    "ResponseResult",
    "load_calibration",
    "write_calibration",
]

FORMAT_VERSION = 1

Vec3 = tuple[float, float, float]
Mat3 = tuple[Vec3, Vec3, Vec3]


class _Closed(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class Provenance(_Closed):
    """When, with what and from which session a section was measured."""

    created: str = Field(description="ISO 8601 time, UTC")
    software: dict[str, str] = Field(default_factory=dict)
    archive: str = Field("", description="the calibration session's archive")

    @classmethod
    def now(cls, archive: str | Path = "", software: dict[str, str] | None = None) -> Provenance:
        return cls(
            created=datetime.now(UTC).isoformat(timespec="seconds"),
            software=dict(software or {}),
            archive=str(archive),
        )


class CameraResult(_Closed):
    K: Mat3
    dist: tuple[float, float, float, float, float]
    R: Mat3
    t: Vec3
    image_size: tuple[int, int]
    rms_px: float = Field(ge=0)
    images: int = Field(ge=0, description="board images used")
    per_image_rms_px: dict[str, float] = Field(default_factory=dict)
    rejected: dict[str, str] = Field(default_factory=dict, description="image → why left out")
    axis_tilt_deg: float | None = None

    def model(self, *, turntable_deg: float = 0.0, scale: float = 1.0) -> PinholeCamera:
        """The calibrated pinhole model, in the sample frame turned by ``turntable_deg``,
        for frames read at ``scale`` × the calibrated size."""
        a = np.deg2rad(turntable_deg)
        Rz = np.array([[np.cos(a), -np.sin(a), 0.0], [np.sin(a), np.cos(a), 0.0], [0.0, 0.0, 1.0]])
        w, h = self.image_size
        camera = PinholeCamera(
            np.array(self.K), np.array(self.dist), np.array(self.R) @ Rz, np.array(self.t), w, h
        )
        return camera if scale == 1.0 else camera.scaled(scale)


class LampResult(_Closed):
    """A distant lamp's ``direction`` or a near lamp's ``position_mm``, in the
    light arc's frame at arc 0° (world frame with the arc at 0°)."""

    direction: Vec3 | None = None
    position_mm: Vec3 | None = None
    intensity: float | None = Field(None, gt=0, description="relative to the brightest lamp")
    residual: float | None = Field(None, ge=0, description="deg (direction) or mm (position)")
    observations: int = Field(0, ge=0)
    clipped: int = Field(0, ge=0, description="highlights clipped by saturation")


class LaserResult(_Closed):
    """A laser mount's sheet angle to the reference plane at the sheet tilt
    ``tilt_deg`` (seed 001 §3.2), with arc and turntable at the session's."""

    angle_deg: float = Field(gt=0, lt=180)
    tilt_deg: float = 0.0
    angle_std_deg: float = Field(ge=0)
    residual_mm: float = Field(ge=0)
    heights: int = Field(ge=2)


class ResponseResult(_Closed):
    """A camera's inverse response: ``curve[v][c]`` is the relative exposure that
    gives value v in channel c (1 at v = 128)."""

    curve: tuple[tuple[float, ...], ...] = Field(description="256 rows: exposure per value")
    exposures: int = Field(ge=2)


class CalibrationFile(_Closed):
    format_version: int = FORMAT_VERSION
    rig: str = ""
    cameras: dict[str, CameraResult] = Field(default_factory=dict)
    cameras_provenance: Provenance | None = None
    lamps: dict[str, LampResult] = Field(default_factory=dict)
    lamps_provenance: Provenance | None = None
    lamps_flat_field: str | None = Field(
        None,
        description="flat-field store beside this file: each lamp's fall-off map "
        "(rig.material.read_flat_field)",
    )
    laser: dict[str, LaserResult] = Field(default_factory=dict, description="per laser mount")
    laser_provenance: Provenance | None = None
    response: dict[str, ResponseResult] = Field(default_factory=dict, description="per camera")
    response_provenance: Provenance | None = None

    def with_section(self, name: str, value, provenance: Provenance) -> CalibrationFile:
        """A copy with section ``name`` replaced (and its provenance)."""
        return self.model_copy(update={name: value, f"{name}_provenance": provenance})

    def camera(self, camera_id: str) -> CameraResult | None:
        return self.cameras.get(camera_id)

    def fitted_to(self, config: RigConfig) -> tuple[CalibrationFile | None, dict[str, str]]:
        """This calibration as far as it fits the rig ``config``, and what was left out
        → why, for a material's record of corrections.

        ``"all"``: ``rig`` names another rig (None: nominal values throughout).
        ``"cameras"`` / ``"lamps"``: the section names a camera or lamp this rig does not
        have (another rig's, or a rig rebuilt since), so none of its ids can be trusted
        to mean this rig's device: the section is left out (the lamps' flat fields with
        it) and the rig config's nominal geometry stands in. A section of fewer devices
        than the rig has (some failed to calibrate) is used for those it has.
        """
        if self.rig and self.rig != config.name:
            return None, {"all": (
                f"the calibration is of rig {self.rig!r}, the archive was recorded on rig "
                f"{config.name!r}: not used, nominal values throughout")}  # fmt: skip
        skipped, update = {}, {}
        sections = {  # section → this rig's ids, and what goes with it
            "cameras": ([c.id for c in config.camera_arc.cameras], {}),
            "lamps": ([lamp.id for lamp in config.lamps], {"lamps_flat_field": None}),
        }
        for name, (ids, also) in sections.items():
            foreign = sorted(set(getattr(self, name)) - set(ids))
            if foreign:
                skipped[name] = (
                    f"the calibration's {name} {', '.join(foreign)} are not this rig's "
                    f"({', '.join(ids)}): another rig's, not used; the rig config's nominal "
                    f"{name}"
                )
                update |= {name: {}, f"{name}_provenance": None, **also}
        return self.model_copy(update=update), skipped

    @classmethod
    def from_dict(cls, data: dict, *, source: str) -> CalibrationFile:
        try:
            cal = cls.model_validate(data)
        except ValidationError as err:
            lines = "\n".join(f"  - {p}" for p in format_validation_error("", err, cls))
            raise ConfigError(f"calibration {source} is not valid:\n{lines}") from err
        if cal.format_version != FORMAT_VERSION:
            raise ConfigError(
                f"calibration {source}: format_version {cal.format_version}, this btfrig "
                f"reads {FORMAT_VERSION}"
            )
        return cal


def load_calibration(path: str | Path) -> CalibrationFile:
    """Read and validate a calibration file; errors name the field."""
    return CalibrationFile.from_dict(read_toml(path, "calibration file"), source=str(path))


def write_calibration(calibration: CalibrationFile, path: str | Path) -> Path:
    """Write atomically (a crash leaves the old file or the new one)."""
    return write_toml(calibration.model_dump(mode="json", exclude_none=True), path)
