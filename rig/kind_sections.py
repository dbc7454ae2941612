"""The config sections of the rig kinds other than the Wang rig: the VirTex stage, the Bonn lab.

A rig config names its ``kind`` (``rig.kinds``); the Wang rig (seed 001:
turntable, light arc, camera arc) is described by ``rig.sections``, the other
kinds by one section each here:

- ``virtex`` (seed 004): one camera straight above the sample and ``lamp_count``
  lamps at one polar angle, at equal azimuth spacing (120° for three). Nothing
  moves; it captures photometric stereo only.
- ``bonn`` (seed 000 §3.1): one fixed lamp, a robot arm holding the sample
  plate and a camera on a circular rail. The *lab frame* has its origin at the
  plate centre (the arm's tool point), z up; the lamp sits on the lab's +x
  axis, the rail is a horizontal circle about the lab's z axis, and rail
  position γ puts the camera at lab azimuth γ. The arm orients the plate:
  at home its normal points horizontally at azimuth ``home_azimuth_deg``
  (between the lamp and the rail), and it may tilt the normal up to
  ``max_tilt_deg`` away from there (``rig.bonn`` has the kinematics).

Lengths in mm, angles in degrees, times in seconds.
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from rig.devices import ArmDevice, DynamixelServos, ModbusDrive, UrController
from rig.parts import Axis, Lamp

__all__ = ["Arm", "BonnLab", "Rail", "RailDevice", "VirtexStage"]

LampKind = Literal["point", "spot", "directional"]


class _Closed(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class VirtexStage(_Closed):
    """Lamps on a ring above the sample (seed 004): lamp *i* at polar angle
    ``lamp_theta_deg`` and azimuth ``phi0_deg + i · 360° / lamp_count``."""

    lamp_theta_deg: float = Field(45.0, gt=0, lt=90, description="polar angle of every lamp")
    lamp_count: int = Field(3, ge=3, le=64, description="lamps on the ring (3: 120° apart)")
    phi0_deg: float = Field(0.0, description="azimuth of lamp0 (sample frame)")
    radius_mm: float = Field(650.0, gt=0, description="lamp distance from the sample centre")
    lamp_kind: LampKind = "point"
    intensity: float = Field(1.0, gt=0, description="relative radiant intensity of each lamp")

    def lamps(self) -> tuple[Lamp, ...]:
        """The ring's lamps ``lamp0 …``, in azimuth order (their lamp-bank channel order)."""
        return tuple(
            Lamp(id=f"lamp{i}", theta_deg=self.lamp_theta_deg, kind=self.lamp_kind,
                 intensity=self.intensity)
            for i in range(self.lamp_count)
        )  # fmt: skip

    def azimuth_deg(self, lamp_index: int) -> float:
        """Azimuth (deg) of lamp ``lamp_index`` in the sample frame."""
        return self.phi0_deg + lamp_index * 360.0 / self.lamp_count


RailDevice = Annotated[ModbusDrive | DynamixelServos, Field(discriminator="kind")]


class Rail(_Closed):
    """The camera's rail: a horizontal circle about the plate; position = camera azimuth.

    The axis range keeps the camera out of the lamp's way (``min_deg``) and
    off the far side of the plate (``max_deg``). Its drive is one of the
    existing axis families (a Modbus stepper or Dynamixel servos).
    """

    radius_mm: float = Field(1200.0, gt=0, description="camera distance from the plate centre")
    axis: Axis = Axis(speed_deg_s=8.0, accel_deg_s2=16.0, settle_s=0.8, min_deg=10.0,
                      max_deg=170.0)  # fmt: skip
    device: RailDevice = DynamixelServos(ids=(11,), gear_ratio=20.0)

    @model_validator(mode="after")
    def _in_front(self) -> Rail:
        if not 0 < self.axis.min_deg < self.axis.max_deg < 180:
            raise ValueError(
                f"axis range [{self.axis.min_deg}, {self.axis.max_deg}]° must lie inside "
                "(0, 180)°: at 0° the camera is in the lamp's beam, at 180° behind the plate"
            )
        return self


class Arm(_Closed):
    """The robot arm holding the plate: where it stands and how far it may tilt the plate.

    Its base sits at ``base_mm`` in the lab frame, axes parallel to the lab's;
    it holds the plate from behind, the plate centre being its tool centre
    point (``device.tcp``). Its speed, acceleration, joint limits and settle
    time are the device's (``rig.devices.UrController``).
    """

    device: ArmDevice = UrController(tcp=(0.0, 0.0, 0.05, 0.0, 0.0, 0.0))
    base_mm: tuple[float, float, float] = Field(
        (-320.0, -320.0, -150.0), description="the arm's base in the lab frame"
    )
    home_azimuth_deg: float = Field(
        45.0, ge=0, le=180, description="lab azimuth of the plate normal at home"
    )
    max_tilt_deg: float = Field(
        120.0, gt=0, le=180, description="largest angle between the plate normal and home"
    )


class BonnLab(_Closed):
    """The Bonn lab (seed 000 §3.1): fixed lamp, arm holding the plate, rail camera."""

    lamp_id: str = "lamp0"
    lamp_kind: LampKind = "point"
    lamp_intensity: float = Field(1.0, gt=0, description="relative radiant intensity")
    lamp_distance_mm: float = Field(2000.0, gt=0, description="lamp distance from the plate")
    rail: Rail = Rail()
    arm: Arm = Arm()

    def lamps(self) -> tuple[Lamp, ...]:
        """The lab's one lamp (its ``theta_deg`` is 0: it lies on the lab's +x axis)."""
        return (
            Lamp(id=self.lamp_id, theta_deg=0.0, kind=self.lamp_kind,
                 intensity=self.lamp_intensity),
        )  # fmt: skip
