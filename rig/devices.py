"""Device sections of a rig config: one tagged union per role, one model per family.

Each role (turntable, light arc, lamp bank, laser unit, camera, and the arm
holding the sample on a rig that has one) has a device section whose ``kind``
names the family that drives it: ``kind = "modbus"``, ``"dynamixel"``,
``"nxt"``, ``"ur"`` (arm), cameras ``"sim"``, ``"opencv"`` or ``"genicam"``.
A family's model holds what a lab writes for its device: where it is (port,
host, unit id, retries) and how this unit is wired (register addresses, status
bits, servo ids, gearing, NXT ports). These are plain data; what the numbers
mean — encoding counts, decoding a status word, degrees to servo ticks — is the
driver family's code in ``drivers/``, and the simulator's peers read the same
data independently. ``docs/devices.md`` lists the files a new family needs:
its model here (and its name in the role's union), a driver, a peer.
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

__all__ = [
    "ACTUATOR_ROLES",
    "ARM_ROLE",
    "CAMERA_ROLE",
    "DEVICE_ROLES",
    "RAIL_ROLE",
    "ArmDevice",
    "CameraConnection",
    "DriveRegisters",
    "DynamixelServos",
    "GenicamConnection",
    "LampBankDevice",
    "LampBankRegisters",
    "LaserDevice",
    "LightArcDevice",
    "ModbusConnection",
    "ModbusDrive",
    "ModbusLamps",
    "NxtLaserUnit",
    "OpenCvConnection",
    "Retry",
    "SimCameraConnection",
    "TurntableDevice",
    "UrController",
]

# Every device role, declared here once.
# The Wang rig's roles with one device each, in the order a rig opens them.
DEVICE_ROLES = ("turntable", "light_arc", "lamp_bank", "laser")
# The robot arm holding the sample, on a rig kind that has one (seed 000's lab).
ARM_ROLE = "arm"
# The rail that carries the camera in seed 000's lab.
RAIL_ROLE = "rail"
# Every role with one device each, whatever the rig kind.
ACTUATOR_ROLES = (*DEVICE_ROLES, ARM_ROLE, RAIL_ROLE)
# The cameras: one device per camera.
CAMERA_ROLE = "camera"


class _Closed(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class Retry(_Closed):
    """Bounded retries with exponential backoff."""

    timeout_s: float = Field(1.0, gt=0, description="per-request timeout")
    retries: int = Field(3, ge=0, le=20, description="extra attempts after the first")
    backoff_s: float = Field(0.05, ge=0, description="first backoff; doubles each retry")


# -- Modbus (turntable drive, lamp bank) -------------------------------------------


class ModbusConnection(_Closed):
    """Where a Modbus device is: TCP ``host:port`` or RTU on ``serial_port``."""

    protocol: Literal["tcp", "rtu"] = "tcp"
    host: str = "127.0.0.1"
    port: int = Field(502, ge=1, le=65535, description="TCP port")
    serial_port: str | None = Field(None, description="RTU: e.g. /dev/ttyUSB0")
    baudrate: int = Field(115200, gt=0)
    unit_id: int = Field(1, ge=0, le=247)
    retry: Retry = Retry()

    @model_validator(mode="after")
    def _rtu_needs_port(self) -> ModbusConnection:
        if self.protocol == "rtu" and not self.serial_port:
            raise ValueError("protocol 'rtu' needs serial_port (e.g. '/dev/ttyUSB0')")
        return self


class DriveRegisters(_Closed):
    """Register map of a stepper drive (Modbus holding registers).

    Addresses are 0-based protocol addresses (register 40001 is address 0).
    Positions are signed 32-bit counts of ``1 / units_per_deg`` degree in two
    registers (``word_order`` says which comes first); speed and acceleration are
    unsigned 16-bit in the same unit per s and per s². Drives differ: map
    yours here. See ``docs/devices.md``.
    """

    target_position: int = Field(0, ge=0, le=65534, description="int32, write")
    actual_position: int = Field(2, ge=0, le=65534, description="int32, read")
    status: int = Field(4, ge=0, le=65535, description="bit field, read")
    command: int = Field(5, ge=0, le=65535, description="write a command code")
    speed: int = Field(6, ge=0, le=65535, description="uint16, units/s")
    acceleration: int = Field(7, ge=0, le=65535, description="uint16, units/s²")
    units_per_deg: float = Field(100.0, gt=0, description="position counts per degree")
    word_order: Literal["high_first", "low_first"] = "high_first"
    moving_bit: int = Field(0, ge=0, le=15)
    in_position_bit: int = Field(1, ge=0, le=15)
    fault_bit: int = Field(2, ge=0, le=15)
    homed_bit: int = Field(3, ge=0, le=15)
    go_code: int = Field(1, ge=0, le=65535, description="command: move to the target")
    home_code: int = Field(2, ge=0, le=65535, description="command: find home, set 0°")
    stop_code: int = Field(3, ge=0, le=65535, description="command: decelerate and stop")

    @model_validator(mode="after")
    def _distinct(self) -> DriveRegisters:
        words = {
            "target_position": {self.target_position, self.target_position + 1},
            "actual_position": {self.actual_position, self.actual_position + 1},
            "status": {self.status},
            "command": {self.command},
            "speed": {self.speed},
            "acceleration": {self.acceleration},
        }
        names = list(words)
        for i, a in enumerate(names):
            for b in names[i + 1 :]:
                if words[a] & words[b]:
                    raise ValueError(
                        f"registers {a} and {b} overlap at {sorted(words[a] & words[b])}"
                    )
        bits = [self.moving_bit, self.in_position_bit, self.fault_bit, self.homed_bit]
        if len(set(bits)) != len(bits):
            raise ValueError(
                f"status bits must differ; got moving/in_position/fault/homed = {bits}"
            )
        codes = [self.go_code, self.home_code, self.stop_code]
        if len(set(codes)) != len(codes):
            raise ValueError(f"command codes must differ; got go/home/stop = {codes}")
        return self


class ModbusDrive(ModbusConnection):
    """A stepper drive on Modbus, turning an axis (``kind = "modbus"``)."""

    kind: Literal["modbus"] = "modbus"
    registers: DriveRegisters = DriveRegisters()


class LampBankRegisters(_Closed):
    """Modbus layout of the lamp bank; lamp *i* is the *i*-th lamp of the light arc.

    Coil ``coils + i`` switches lamp *i*; discrete input ``light_sensors + i``
    is 1 while its light sensor (photodiode or current sense) sees the lamp
    lit; with ``dimming``, holding register ``dimmers + i`` sets its level in
    ``0..dim_full_scale``. Addresses are 0-based. See ``docs/devices.md``.
    """

    coils: int = Field(0, ge=0, le=65535, description="first lamp's on/off coil")
    light_sensors: int = Field(0, ge=0, le=65535, description="first lamp's light-sensor input")
    dimming: bool = Field(False, description="the bank has dimming holding registers")
    dimmers: int = Field(0, ge=0, le=65535, description="first lamp's dimming register")
    dim_full_scale: int = Field(1000, gt=0, le=65535, description="register value at 100 %")


class ModbusLamps(ModbusConnection):
    """A relay/dimmer module on Modbus switching the lamps (``kind = "modbus"``)."""

    kind: Literal["modbus"] = "modbus"
    registers: LampBankRegisters = LampBankRegisters()


# -- Dynamixel (light arc) ---------------------------------------------------------


class DynamixelServos(_Closed):
    """X-series servos on one Protocol 2.0 bus turning an axis (``kind = "dynamixel"``).

    All ``ids`` get the same goal. The axis angle is ``(ticks - zero_tick) /
    ticks_per_rev / gear_ratio`` turns; profile values are raw control-table
    units, derived from the axis's speed and acceleration when unset.
    """

    kind: Literal["dynamixel"] = "dynamixel"
    serial_port: str = "/dev/ttyUSB0"
    baudrate: int = Field(57600, gt=0)
    retry: Retry = Retry()
    ids: tuple[int, ...] = Field((1,), description="Dynamixel ids driving the axis")
    ticks_per_rev: int = Field(4096, gt=0, description="encoder ticks per servo turn")
    gear_ratio: float = Field(1.0, gt=0, description="servo turns per axis turn")
    zero_tick: int = Field(0, description="present position (ticks) at axis 0°")
    profile_velocity: int | None = Field(
        None, ge=1, le=32767, description="raw, 0.229 rpm units; None: from the axis speed"
    )
    profile_acceleration: int | None = Field(
        None, ge=1, le=32767, description="raw, 214.577 rev/min² units; None: from the axis"
    )

    @model_validator(mode="after")
    def _ids(self) -> DynamixelServos:
        ids = self.ids
        if not ids or len(set(ids)) != len(ids) or not all(0 <= i <= 252 for i in ids):
            raise ValueError(f"ids need unique Dynamixel ids in 0..252, at least one; got {ids}")
        return self


# -- LEGO NXT (laser unit) -----------------------------------------------------------


class NxtLaserUnit(_Closed):
    """The laser unit's LEGO NXT brick and how it is wired (``kind = "nxt"``).

    Reached over USB (pyusb) or Bluetooth SPP (serial). Output ``motor_port``
    tilts the sheet through a gearbox of ``gear_ratio`` degrees of tilt per
    motor degree; output ``laser_port`` powers the diode. A second mount on
    the arc (``laser.mount_theta_deg``) has its diode on the brick's third
    output; the one motor tilts both emitters (their tilt axes are parallel,
    both across the arc), and one diode is lit at a time.
    """

    kind: Literal["nxt"] = "nxt"
    transport: Literal["usb", "serial"] = "usb"
    serial_port: str | None = Field(None, description="serial: the SPP device, e.g. /dev/rfcomm0")
    usb_vendor: int = 0x0694
    usb_product: int = 0x0002
    retry: Retry = Retry()
    motor_port: Literal["A", "B", "C"] = Field("A", description="NXT output that tilts the sheet")
    laser_port: Literal["A", "B", "C"] = Field(
        "B", description="NXT output that powers the laser diode (constant power)"
    )
    gear_ratio: float = Field(
        1 / 24, gt=0, le=10, description="degrees of sheet tilt per motor degree (24:1 worm: 1/24)"
    )
    motor_power: int = Field(30, ge=1, le=100, description="NXT power set point while tilting, %")
    laser_power: int = Field(100, ge=1, le=100, description="NXT power on the laser port, %")
    min_battery_mv: int = Field(
        6500, ge=0, le=10000, description="refuse to scan below this battery voltage (mV)"
    )
    stall_timeout_s: float = Field(
        1.0, gt=0, description="no tacho progress for this long while running: stalled"
    )

    @model_validator(mode="after")
    def _wiring(self) -> NxtLaserUnit:
        if self.transport == "serial" and not self.serial_port:
            raise ValueError("transport 'serial' needs serial_port (e.g. '/dev/rfcomm0')")
        if self.motor_port == self.laser_port:
            raise ValueError(
                f"motor_port and laser_port are both {self.motor_port!r}; use two NXT outputs"
            )
        return self

    def diode_ports(self, mounts: int) -> tuple[str, ...]:
        """The output powering each of ``mounts`` mounts' diodes: ``laser_port``,
        then the output that is neither it nor ``motor_port``."""
        if not 1 <= mounts <= 2:
            raise ValueError(
                f"an NXT laser unit lights 1 or 2 mounts (its three outputs: the tilt motor "
                f"and a diode per mount), not {mounts}"
            )
        spare = next(p for p in "ABC" if p not in (self.motor_port, self.laser_port))
        return (self.laser_port, spare)[:mounts]


# -- Universal Robots arm (holds the sample) ------------------------------------------


class UrController(_Closed):
    """A Universal Robots arm's controller on the network (``kind = "ur"``).

    The driver sends URScript to ``realtime_port`` and reads the controller's
    state stream from it (the CB3 3.10+ / e-Series 5.4+ layout of 1116 bytes),
    and uses the dashboard server on ``dashboard_port`` for power, brakes and
    protective stops. ``model`` picks the published DH parameters the pose
    checks use (``rig.ur_kinematics``); ``tcp`` is the tool centre point on
    the flange (the sample's centre), sent with every move. Joint speed and
    acceleration apply to every joint. See ``docs/devices.md``.
    """

    kind: Literal["ur"] = "ur"
    host: str = "127.0.0.1"
    dashboard_port: int = Field(29999, ge=1, le=65535, description="dashboard server")
    realtime_port: int = Field(30003, ge=1, le=65535, description="URScript in, state out")
    retry: Retry = Retry()
    model: Literal["ur3e", "ur5e", "ur10e"] = "ur5e"
    tcp: tuple[float, float, float, float, float, float] = Field(
        (0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
        description="tool centre point on the flange: x, y, z (m), rotation vector (rad)",
    )
    joint_speed_deg_s: float = Field(60.0, gt=0, le=180, description="every joint")
    joint_accel_deg_s2: float = Field(80.0, gt=0, le=800, description="every joint")
    joint_min_deg: tuple[float, float, float, float, float, float] = (-360.0,) * 6
    joint_max_deg: tuple[float, float, float, float, float, float] = (360.0,) * 6
    settle_s: float = Field(0.5, ge=0, description="wait after a move before an exposure")
    poll_s: float = Field(0.02, gt=0, le=1, description="state reads while a move runs")
    position_tolerance_deg: float = Field(
        0.05, gt=0, le=5, description="a joint within this of its target has arrived"
    )
    unlock_wait_s: float = Field(
        6.0, ge=0, le=60, description="how long to keep retrying a refused protective-stop unlock"
    )

    @model_validator(mode="after")
    def _limits(self) -> UrController:
        for i, (lo, hi) in enumerate(zip(self.joint_min_deg, self.joint_max_deg, strict=True)):
            if not -360.0 <= lo < hi <= 360.0:
                raise ValueError(
                    f"joint {i + 1} limits [{lo}°, {hi}°] must satisfy -360 ≤ min < max ≤ 360"
                )
        return self


# -- Cameras -------------------------------------------------------------------------


class SimCameraConnection(_Closed):
    """The simulator's camera server at ``url`` (e.g. ``tcp://127.0.0.1:5600``)."""

    kind: Literal["sim"] = "sim"
    url: str = "tcp://127.0.0.1:5600"
    retry: Retry = Retry()


class OpenCvConnection(_Closed):
    """A V4L2/UVC device index (``"0"``) or an image-sequence pattern in ``url``."""

    kind: Literal["opencv"] = "opencv"
    url: str = Field(description="device index or printf pattern, e.g. frames/img_%04d.png")
    retry: Retry = Retry()


class GenicamConnection(_Closed):
    """A GenICam camera: the GenTL producer ``cti`` file and the device's serial in ``url``."""

    kind: Literal["genicam"] = "genicam"
    url: str = Field(description="the device's serial number")
    cti: str = Field(description="the GenTL producer file (.cti)")
    retry: Retry = Retry()


# -- one union per role: a new family adds its model to its role's union ---------------

TurntableDevice = Annotated[ModbusDrive, Field(discriminator="kind")]
LightArcDevice = Annotated[DynamixelServos, Field(discriminator="kind")]
LampBankDevice = Annotated[ModbusLamps, Field(discriminator="kind")]
LaserDevice = Annotated[NxtLaserUnit, Field(discriminator="kind")]
ArmDevice = Annotated[UrController, Field(discriminator="kind")]
CameraConnection = Annotated[
    SimCameraConnection | OpenCvConnection | GenicamConnection, Field(discriminator="kind")
]
