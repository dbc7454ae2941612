"""How the daemon reaches each device: ports, addresses, timeouts, retries.

These are plain data; the drivers in ``drivers/`` take them. The same driver
code serves real hardware and the simulator: only these values differ (a
``/dev/ttyUSB0`` or a pty, a drive's IP or 127.0.0.1).
"""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

__all__ = [
    "CameraConnection",
    "DynamixelConnection",
    "ModbusConnection",
    "NxtConnection",
    "Retry",
]


class _Closed(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class Retry(_Closed):
    """Bounded retries with exponential backoff."""

    timeout_s: float = Field(1.0, gt=0, description="per-request timeout")
    retries: int = Field(3, ge=0, le=20, description="extra attempts after the first")
    backoff_s: float = Field(0.05, ge=0, description="first backoff; doubles each retry")


class ModbusConnection(_Closed):
    """A Modbus device (turntable drive, lamp bank) over TCP or RTU (serial)."""

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


class DynamixelConnection(_Closed):
    """A Dynamixel Protocol 2.0 bus (serial adapter or a pty in the simulator)."""

    serial_port: str = "/dev/ttyUSB0"
    baudrate: int = Field(57600, gt=0)
    retry: Retry = Retry()


class NxtConnection(_Closed):
    """A LEGO NXT brick over USB (pyusb) or Bluetooth SPP (serial)."""

    transport: Literal["usb", "serial"] = "usb"
    serial_port: str | None = Field(None, description="serial: the SPP device, e.g. /dev/rfcomm0")
    usb_vendor: int = 0x0694
    usb_product: int = 0x0002
    retry: Retry = Retry()

    @model_validator(mode="after")
    def _serial_needs_port(self) -> NxtConnection:
        if self.transport == "serial" and not self.serial_port:
            raise ValueError("transport 'serial' needs serial_port (e.g. '/dev/rfcomm0')")
        return self


class CameraConnection(_Closed):
    """Where a camera's frames come from.

    ``sim``: the simulator's camera server at ``url`` (e.g. ``tcp://127.0.0.1:5600``);
    ``opencv``: a V4L2/UVC device index or an image-sequence pattern in ``url``;
    ``genicam``: a GenTL producer ``cti`` file and the device's serial in ``url``.
    """

    kind: Literal["sim", "opencv", "genicam"] = "sim"
    url: str = "tcp://127.0.0.1:5600"
    cti: str | None = None
    retry: Retry = Retry()

    @model_validator(mode="after")
    def _genicam_needs_cti(self) -> CameraConnection:
        if self.kind == "genicam" and not self.cti:
            raise ValueError("kind 'genicam' needs cti (the GenTL producer file)")
        return self
