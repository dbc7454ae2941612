"""The rig config: its kind, geometry, motion and timing, and its devices.

``kind`` names the rig design: ``wang`` (the default, below), ``virtex`` or
``bonn`` (their geometry is their own section, ``rig.kinds``). On a Wang rig a
turntable carries the sample; a light arc rotates about the vertical axis and
carries N lamps (and the laser unit); a fixed camera arc carries M cameras. All
positions are in the *world* (turntable) frame: origin at the turntable centre
on the reference plane (the top of the holder plate), z up, x towards the
camera arc at azimuth 0. Lengths in mm, angles in degrees, times in seconds.

Arc positions use a signed polar angle: a lamp at ``theta_deg = -30`` sits on
the far half of its arc, i.e. at azimuth (arc angle + 180°).
"""

from __future__ import annotations

import reprlib
import tomllib
from pathlib import Path
from typing import Literal

import numpy as np
import tomli_w
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from rig.camera import PinholeCamera, look_at
from rig.config_migration import CONFIG_VERSION, migrate_rig_config
from rig.devices import (
    ARM_ROLE,
    DEVICE_ROLES,
    CameraConnection,
    DynamixelServos,
    GenicamConnection,
    LampBankDevice,
    LaserDevice,
    LightArcDevice,
    ModbusDrive,
    ModbusLamps,
    NxtLaserUnit,
    OpenCvConnection,
    SimCameraConnection,
    TurntableDevice,
)
from rig.errors import ConfigError
from rig.geometry import direction_vector
from rig.kinds import RAIL_ROLE, RIG_KINDS, BonnLab, VirtexStage
from rig.parts import Axis, Lamp, SignedPolar
from rig.targets import Targets

__all__ = [
    "RIG_KINDS",
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
    "file_text",
    "format_validation_error",
    "load_rig_config",
    "read_toml",
    "toml_data",
    "write_rig_config",
]


class _Closed(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class Turntable(_Closed):
    """The rotary stage under the sample: its motion limits and the device turning it."""

    axis: Axis = Axis(speed_deg_s=30.0, accel_deg_s2=60.0, settle_s=0.3)
    device: TurntableDevice = ModbusDrive(port=5020)


class LampBank(_Closed):
    """The lamps' power switches; lamp *i* is the *i*-th lamp of the light arc."""

    device: LampBankDevice = ModbusLamps(port=5021)
    warmup_s: float = Field(0.05, ge=0, description="from switching on to stable light")


_H2_THETAS = (0.0, 15.0, 30.0, 45.0, 60.0, 75.0, 34.0, 68.0)


class LightArc(_Closed):
    radius_mm: float = Field(650.0, gt=0)
    axis: Axis = Axis(speed_deg_s=20.0, accel_deg_s2=40.0, settle_s=0.5)
    lamps: tuple[Lamp, ...] = tuple(
        Lamp(id=f"lamp{i}", theta_deg=t) for i, t in enumerate(_H2_THETAS)
    )
    device: LightArcDevice = DynamixelServos()

    @model_validator(mode="after")
    def _unique_lamps(self) -> LightArc:
        ids = [lamp.id for lamp in self.lamps]
        if len(set(ids)) != len(ids) or not ids:
            raise ValueError(f"lamps need unique ids, at least one; got {ids}")
        return self


class CameraSpec(_Closed):
    """One camera on the camera arc, pointing at the turntable centre."""

    id: str
    theta_deg: SignedPolar
    width: int = Field(1024, gt=0, le=16384)
    height: int = Field(768, gt=0, le=16384)
    fx_px: float = Field(3000.0, gt=0)
    fy_px: float = Field(3000.0, gt=0)
    cx_px: float | None = None
    cy_px: float | None = None
    dist: tuple[float, float, float, float, float] = (0.0, 0.0, 0.0, 0.0, 0.0)
    channels: Literal[1, 3] = 3
    bit_depth: Literal[8, 10, 12, 16] = 8
    readout_s: float = Field(1 / 15, ge=0, description="sensor readout per frame")
    connection: CameraConnection = SimCameraConnection()

    @property
    def device(self) -> SimCameraConnection | OpenCvConnection | GenicamConnection:
        """The camera's device section (its ``connection``), as for the other roles."""
        return self.connection


class CameraArc(_Closed):
    radius_mm: float = Field(800.0, gt=0)
    azimuth_deg: float = Field(0.0, description="azimuth of the arc's plane (world)")
    cameras: tuple[CameraSpec, ...] = tuple(
        CameraSpec(id=f"cam{i}", theta_deg=t) for i, t in enumerate(_H2_THETAS)
    )

    @model_validator(mode="after")
    def _unique_cameras(self) -> CameraArc:
        ids = [cam.id for cam in self.cameras]
        if len(set(ids)) != len(ids) or not ids:
            raise ValueError(f"cameras need unique ids, at least one; got {ids}")
        return self


class Laser(_Closed):
    """The LEGO laser unit on the light arc: it tilts the laser sheet to sweep it.

    ``mount_theta_deg`` holds one angle per emitter on the arc (signed: a
    negative angle is on the arc's other side); a second, steeper mount
    reaches recesses a 45° sheet cannot (docs/mdf.md, coverage).
    """

    mount_theta_deg: tuple[SignedPolar, ...] = (45.0,)
    radius_mm: float = Field(500.0, gt=0, description="distance from the turntable centre")
    sweep_deg: float = Field(12.0, gt=0, le=90, description="total tilt of the sheet per scan")
    sweep_speed_deg_s: float = Field(1.0, gt=0, description="tilt speed while scanning")
    frame_rate_hz: float = Field(7.5, gt=0, description="camera rate while scanning")
    tilt_limit_deg: float = Field(30.0, gt=0, le=90, description="mechanical tilt range: ±limit")
    device: LaserDevice = NxtLaserUnit()

    @model_validator(mode="after")
    def _sweep_in_range(self) -> Laser:
        if self.sweep_deg / 2 > self.tilt_limit_deg:
            raise ValueError(
                f"sweep_deg {self.sweep_deg} exceeds the tilt range ±{self.tilt_limit_deg}"
            )
        try:
            self.device.diode_ports(len(self.mount_theta_deg))
        except ValueError as err:
            raise ValueError(f"mount_theta_deg {list(self.mount_theta_deg)}: {err}") from None
        return self


class Holder(_Closed):
    """The holder plate: the sample in the middle, ArUco markers around it."""

    plate_mm: float = Field(180.0, gt=0, description="side of the square plate")
    sample_mm: float = Field(100.0, gt=0, description="side of the square sample area")
    marker_mm: float = Field(14.0, gt=0, description="side of one ArUco marker")
    aruco_dictionary: str = "DICT_4X4_50"
    markers_per_side: int = Field(4, ge=1, le=12)

    @model_validator(mode="after")
    def _fits(self) -> Holder:
        border = (self.plate_mm - self.sample_mm) / 2
        if border < self.marker_mm * 1.2:
            raise ValueError(
                f"the border between sample ({self.sample_mm} mm) and plate edge "
                f"({border:.1f} mm) must hold a marker of {self.marker_mm} mm with margin"
            )
        spacing = self._spacing_mm()
        if spacing < self.marker_mm * 1.2:
            most = int(2 * self._mid_mm() // (self.marker_mm * 1.2))
            raise ValueError(
                f"markers_per_side={self.markers_per_side}: markers {spacing:.1f} mm apart "
                f"would touch (marker_mm={self.marker_mm}); at most {most} fit per side"
            )
        return self

    def _mid_mm(self) -> float:
        return (self.plate_mm + self.sample_mm) / 4  # middle of the border strip

    def _spacing_mm(self) -> float:
        return 2 * self._mid_mm() / self.markers_per_side

    def marker_centers_mm(self) -> np.ndarray:
        """(n, 2) marker centres on the plate (sample frame, mm), ids in order.

        The markers walk counter-clockwise around the middle of the border strip,
        evenly spaced; each side starts at a corner and owns it, so no two overlap.
        """
        mid = self._mid_mm()
        ticks = -mid + self._spacing_mm() * np.arange(self.markers_per_side)
        sides = [
            np.column_stack([ticks, np.full_like(ticks, -mid)]),
            np.column_stack([np.full_like(ticks, mid), ticks]),
            np.column_stack([-ticks, np.full_like(ticks, mid)]),
            np.column_stack([np.full_like(ticks, -mid), -ticks]),
        ]
        return np.vstack(sides)


class RigConfig(_Closed):
    """Everything the daemon, the simulator and the planner know about a rig.

    ``version`` is the layout of the file; older layouts are migrated when read
    (``rig.config_migration``), so configs stored in old archives still load.
    """

    version: Literal[2] = Field(CONFIG_VERSION, description="layout of this config")
    name: str = "default"
    kind: Literal["wang", "bonn", "virtex"] = Field("wang", description="the rig design")
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
        if data.get("kind") in ("virtex", "bonn") and "camera_arc" not in data:
            # one camera: straight above the VirTex stage, on the Bonn lab's rail
            data = {**data, "camera_arc": {"cameras": [{"id": "cam0", "theta_deg": 0.0}]}}
        return data

    @model_validator(mode="after")
    def _kind_sections(self) -> RigConfig:
        for other in ("virtex", "bonn"):
            if other != self.kind and getattr(self, other) is not None:
                raise ValueError(
                    f"[{other}] describes a {other!r} rig but kind is {self.kind!r}; "
                    f"set kind = {other!r} or remove [{other}]"
                )
        if self.kind != "wang" and getattr(self, self.kind) is None:
            raise ValueError(f"kind {self.kind!r} needs its [{self.kind}] section")
        cameras = self.camera_arc.cameras
        if self.kind == "bonn" and len(cameras) != 1:
            raise ValueError(
                f"camera_arc.cameras: the Bonn lab has one camera, on its rail; got "
                f"{[c.id for c in cameras]}"
            )
        if self.kind == "virtex":
            oblique = [c.id for c in cameras if c.theta_deg != 0.0]
            if oblique:
                raise ValueError(
                    f"camera_arc.cameras {oblique}: a VirTex stage's camera looks straight "
                    "down at the sample; set theta_deg = 0"
                )
        return self

    @property
    def lamps(self) -> tuple[Lamp, ...]:
        """The rig's lamps, in lamp-bank channel order."""
        if self.kind == "virtex":
            return self.virtex.lamps()
        if self.kind == "bonn":
            return self.bonn.lamps()
        return self.light_arc.lamps

    @property
    def device_roles(self) -> tuple[str, ...]:
        """The device roles this kind of rig has, cameras aside, in the order it opens them
        (a Wang rig: ``rig.devices.DEVICE_ROLES``)."""
        roles = {"virtex": ("lamp_bank",), "bonn": (ARM_ROLE, RAIL_ROLE, "lamp_bank")}
        return roles.get(self.kind, DEVICE_ROLES)

    def device_section(self, role: str):
        """The config section of ``role`` (one of :attr:`device_roles`): it has a ``device``."""
        if role not in self.device_roles:
            raise ConfigError(
                f"a {self.kind!r} rig has no {role}; its devices are {list(self.device_roles)}"
            )
        if self.kind == "bonn" and role in (ARM_ROLE, RAIL_ROLE):
            return getattr(self.bonn, role)
        return getattr(self, role)

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


def _locate(model: type[BaseModel] | None, loc: tuple) -> tuple[tuple, type[BaseModel] | None]:
    """``loc`` without the tags pydantic adds for tagged unions, and the model that
    holds its last part (None where the walk cannot tell)."""
    shown: list = []
    parts = list(loc)
    while parts:
        part = parts.pop(0)
        shown.append(part)
        if not parts:
            break
        if model is None or not isinstance(part, str) or part not in model.model_fields:
            model = None
            continue
        members = _models_in(model.model_fields[part].annotation)
        if parts and isinstance(parts[0], int):  # an item of a list of models
            shown.append(parts.pop(0))
        kinds = {_kind_of(m): m for m in members}
        if parts and len(parts) > 1 and parts[0] in kinds:  # a tagged union's tag
            model = kinds[parts.pop(0)]
        else:
            model = members[0] if len(members) == 1 else None
    return tuple(shown), model


def _models_in(annotation) -> list[type[BaseModel]]:
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return [annotation]
    found: list[type[BaseModel]] = []
    for arg in getattr(annotation, "__args__", ()) + getattr(annotation, "__metadata__", ()):
        found += [m for m in _models_in(arg) if m not in found]
    origin = getattr(annotation, "__origin__", None)
    return found or (_models_in(origin) if origin is not None else [])


def _kind_of(model: type[BaseModel]) -> str | None:
    field = model.model_fields.get("kind")
    return field.default if field is not None else None


# A value shown in an error: a few levels and items, so a huge or deeply nested
# input gives a short line.
_SHORT = reprlib.Repr()
_SHORT.maxlevel, _SHORT.maxlist, _SHORT.maxtuple, _SHORT.maxstring = 3, 6, 6, 80


def format_validation_error(
    source: str, err: ValidationError, model: type[BaseModel] | None = None
) -> list[str]:
    """One line per problem: the field's dotted path, the value, what is valid.

    With ``model`` (the root model validated), an unknown field's line lists
    the valid field names at that place.
    """
    lines = []
    for e in err.errors():
        loc, holder = _locate(model, e["loc"])
        where = ".".join(str(p) for p in loc) or "(top level)"
        value = e.get("input")
        if e["type"] == "extra_forbidden":
            hint = f"; valid fields here are {sorted(holder.model_fields)}" if holder else ""
            lines.append(f"{where}: unknown field{hint}")
            continue
        if e["type"] in ("union_tag_invalid", "union_tag_not_found"):
            tag = e.get("ctx", {}).get("tag")
            got = f"kind {tag!r} is not known here" if tag is not None else "kind is missing"
            valid = e.get("ctx", {}).get("expected_tags")
            if valid is None and holder is not None and loc[-1] in holder.model_fields:
                members = _models_in(holder.model_fields[loc[-1]].annotation)
                valid = ", ".join(repr(_kind_of(m)) for m in members)
            lines.append(f"{where}: {got}" + (f"; valid kinds are {valid}" if valid else ""))
            continue
        msg = e["msg"].removeprefix("Value error, ")
        shown = "" if isinstance(value, dict) else f" (got {_SHORT.repr(value)})"
        lines.append(f"{where}: {msg}{shown}")
    return lines


def file_text(path: Path) -> str:
    """The UTF-8 text of file ``path``; a ``ValueError`` saying why it cannot be
    read ("does not exist", "is a folder, not a TOML file", …)."""
    try:
        return path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ValueError("does not exist") from None
    except IsADirectoryError:
        raise ValueError("is a folder, not a TOML file") from None
    except UnicodeDecodeError as err:
        raise ValueError(
            f"is not UTF-8 text (byte {err.start} is {err.object[err.start]:#04x}); "
            "give a TOML text file"
        ) from None
    except OSError as err:
        raise ValueError(f"cannot be read: {err.strerror}") from None


def toml_data(text: str) -> dict:
    """The data of TOML ``text``; a ``ValueError`` saying why it is not TOML."""
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise ValueError(f"is not valid TOML: {err}") from None
    except RecursionError:
        # tomllib parses nested arrays and inline tables recursively
        raise ValueError("nests arrays or inline tables too deeply to be read") from None


def read_toml(path: str | Path, what: str) -> dict:
    """The data of TOML file ``path``; a ``ConfigError`` naming ``what``, the
    file and why when it cannot be read or is not TOML."""
    try:
        return toml_data(file_text(Path(path)))
    except ValueError as err:
        raise ConfigError(f"{what} {path} {err}") from None


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
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(tomli_w.dumps(config.model_dump(mode="json", exclude_none=True)))
    return path


def default_rig_config() -> RigConfig:
    """The default Wang-style rig: 8 cameras and 8 lamps at the H2 ring angles
    (plus 34° and 68° of H1), turntable and light arc, one laser unit."""
    return RigConfig()
