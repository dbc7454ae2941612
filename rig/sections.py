"""The rig config's sections: the Wang rig's parts and the parts every kind has.

A Wang rig (seed 001, the default kind) is a ``Turntable`` carrying the sample,
a ``LightArc`` rotating about the vertical axis with N lamps (and the ``Laser``
unit), and a fixed ``CameraArc`` with M cameras. Every kind has a camera arc
(the VirTex stage and the Bonn lab: one camera on it), a ``LampBank`` switching
the lamps, and the sample's ``Holder`` plate; the other kinds' own geometry is
in ``rig.kind_sections``. All positions are in the *world* (turntable) frame: origin at
the turntable centre on the reference plane (the top of the holder plate), z up,
x towards the camera arc at azimuth 0. Lengths in mm, angles in degrees, times
in seconds.

Arc positions use a signed polar angle: a lamp at ``theta_deg = -30`` sits on
the far half of its arc, i.e. at azimuth (arc angle + 180°).
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

from rig.devices import (
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
from rig.parts import Axis, Lamp, SignedPolar

__all__ = ["CameraArc", "CameraSpec", "Holder", "LampBank", "Laser", "LightArc", "Turntable"]


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
