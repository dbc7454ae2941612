"""The rig config: its kind, its sections, and reading and writing it as TOML.

``kind`` names the rig design (``rig.kinds``): ``wang`` (the default), ``virtex``
or ``bonn``. The sections of the Wang rig's parts and those every kind has
(camera arc, lamp bank, holder) are in ``rig.sections``; the other kinds'
geometry is one section each (``rig.kind_sections``). ``RigConfig`` asks its
kind whether the sections fit and what its lamps and device roles are. All
positions are in the *world* (turntable) frame: origin at the turntable centre
on the reference plane (the top of the holder plate), z up, x towards the
camera arc at azimuth 0. Lengths in mm, angles in degrees, times in seconds.
"""

from __future__ import annotations

from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from rig.camera import PinholeCamera, look_at
from rig.config_migration import CONFIG_VERSION, migrate_rig_config
from rig.errors import ConfigError
from rig.geometry import direction_vector
from rig.kind_sections import BonnLab, VirtexStage
from rig.kinds import kind_names, rig_kind
from rig.parts import Axis, Lamp
from rig.sections import (
    CameraArc,
    CameraSpec,
    Holder,
    LampBank,
    Laser,
    LightArc,
    Turntable,
)
from rig.targets import Targets
from rig.tomlfile import format_validation_error, read_toml, write_toml

__all__ = [
    "Axis",
    "CameraArc",
    "CameraSpec",
    "Holder",
    "Lamp",
    "LampBank",
    "Laser",
    "LightArc",
    "RigConfig",
    "Turntable",
    "default_rig_config",
    "load_rig_config",
    "write_rig_config",
]


class RigConfig(BaseModel):
    """Everything the daemon, the simulator and the planner know about a rig.

    ``version`` is the layout of the file; older layouts are migrated when read
    (``rig.config_migration``), so configs stored in old archives still load.
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    version: Literal[2] = Field(CONFIG_VERSION, description="layout of this config")
    name: str = "default"
    kind: str = Field("wang", description="the rig design (rig.kinds)")
    turntable: Turntable = Turntable()
    light_arc: LightArc = LightArc()
    lamp_bank: LampBank = LampBank()
    camera_arc: CameraArc = CameraArc()
    laser: Laser = Laser()
    holder: Holder = Holder()
    targets: Targets = Targets()
    calibration: str | None = Field(None, description="path of a calibration file")
    virtex: VirtexStage | None = Field(None, description="kind 'virtex': the lamp ring")
    bonn: BonnLab | None = Field(None, description="kind 'bonn': lamp, rail and arm")

    @model_validator(mode="before")
    @classmethod
    def _migrate(cls, data):
        if not isinstance(data, dict):
            return data
        data = migrate_rig_config(data)
        kind = data.get("kind", "wang")
        if isinstance(kind, str) and kind in kind_names():  # else the field says what is valid
            data = rig_kind(kind).config_defaults(data)
        return data

    @field_validator("kind")
    @classmethod
    def _known_kind(cls, kind: str) -> str:
        if kind not in kind_names():
            raise ValueError(f"unknown rig kind {kind!r}; valid are {kind_names()}")
        return kind

    @model_validator(mode="after")
    def _kind_sections(self) -> RigConfig:
        mine = rig_kind(self).section
        for other in _KIND_SECTIONS:
            if other != mine and getattr(self, other) is not None:
                raise ValueError(
                    f"[{other}] describes a {other!r} rig but kind is {self.kind!r}; "
                    f"set kind = {other!r} or remove [{other}]"
                )
        if mine is not None and getattr(self, mine) is None:
            raise ValueError(f"kind {self.kind!r} needs its [{mine}] section")
        rig_kind(self).check(self)
        return self

    @property
    def lamps(self) -> tuple[Lamp, ...]:
        """The rig's lamps, in lamp-bank channel order."""
        return rig_kind(self).lamps(self)

    @property
    def device_roles(self) -> tuple[str, ...]:
        """The device roles this kind of rig has, cameras aside, in the order it opens them
        (a Wang rig: ``rig.devices.DEVICE_ROLES``)."""
        return rig_kind(self).device_roles

    def device_section(self, role: str):
        """The config section of ``role`` (one of :attr:`device_roles`): it has a ``device``."""
        if role not in self.device_roles:
            raise ConfigError(
                f"a {self.kind!r} rig has no {role}; its devices are {list(self.device_roles)}"
            )
        return rig_kind(self).device_section(self, role)

    def camera(self, camera_id: str) -> CameraSpec:
        for cam in self.camera_arc.cameras:
            if cam.id == camera_id:
                return cam
        valid = [c.id for c in self.camera_arc.cameras]
        raise ConfigError(f"unknown camera {camera_id!r}; this rig has {valid}")

    def lamp(self, lamp_id: str) -> Lamp:
        for lamp in self.lamps:
            if lamp.id == lamp_id:
                return lamp
        valid = [lamp.id for lamp in self.lamps]
        raise ConfigError(f"unknown lamp {lamp_id!r}; this rig has {valid}")

    def camera_model(self, camera_id: str, *, turntable_deg: float = 0.0) -> PinholeCamera:
        """The nominal (uncalibrated) pinhole model of a camera.

        In the world frame at ``turntable_deg = 0``; otherwise in the sample
        frame of a sample turned by ``turntable_deg`` (x_cam = R·Rz(α)·x_sample + t).
        """
        cam = self.camera(camera_id)
        eye = self.camera_arc.radius_mm * arc_direction(cam.theta_deg, self.camera_arc.azimuth_deg)
        R, t = look_at(eye, np.zeros(3), up=_arc_up(cam.theta_deg, self.camera_arc.azimuth_deg))
        a = np.deg2rad(turntable_deg)
        Rz = np.array([[np.cos(a), -np.sin(a), 0.0], [np.sin(a), np.cos(a), 0.0], [0.0, 0.0, 1.0]])
        R = R @ Rz
        cx = (cam.width - 1) / 2 if cam.cx_px is None else cam.cx_px
        cy = (cam.height - 1) / 2 if cam.cy_px is None else cam.cy_px
        K = np.array([[cam.fx_px, 0, cx], [0, cam.fy_px, cy], [0, 0, 1.0]])
        return PinholeCamera(K, np.array(cam.dist), R, t, cam.width, cam.height)


#: The config fields that hold one kind's own geometry.
_KIND_SECTIONS = ("virtex", "bonn")


def arc_direction(signed_theta_deg, arc_azimuth_deg) -> np.ndarray:
    """World unit vector of a signed polar position on an arc at an azimuth."""
    theta = np.asarray(signed_theta_deg, dtype=np.float64)
    phi = np.asarray(arc_azimuth_deg, dtype=np.float64) + np.where(theta < 0, 180.0, 0.0)
    return direction_vector(np.abs(theta), phi)


def _arc_up(signed_theta_deg: float, arc_azimuth_deg: float) -> np.ndarray:
    # Image "up" points along the arc towards the zenith, so frontal and
    # oblique cameras share an orientation (x of the image ≈ world y).
    phi = np.deg2rad(arc_azimuth_deg)
    return (
        np.array([-np.cos(phi), -np.sin(phi), 0.0])
        if abs(signed_theta_deg) < 1e-9
        else (np.array([0.0, 0.0, 1.0]))
    )


def load_rig_config(path: str | Path) -> RigConfig:
    """Read and validate a rig config TOML file; errors name file and fields."""
    path = Path(path)
    data = read_toml(path, "rig config")
    try:
        return RigConfig.model_validate(data)
    except ValidationError as err:
        lines = "\n".join(
            f"  - {line}" for line in format_validation_error(str(path), err, RigConfig)
        )
        raise ConfigError(f"rig config {path}: invalid\n{lines}") from err


def write_rig_config(config: RigConfig, path: str | Path) -> Path:
    """Write ``config`` as TOML that :func:`load_rig_config` reads back equal."""
    return write_toml(config.model_dump(mode="json", exclude_none=True), path)


def default_rig_config() -> RigConfig:
    """The default Wang-style rig: 8 cameras and 8 lamps at the H2 ring angles
    (plus 34° and 68° of H1), turntable and light arc, one laser unit."""
    return RigConfig()
