"""Device errors: each names the device, the operation and the value involved."""

from __future__ import annotations

from rig.errors import RigError

__all__ = ["DeviceError", "DeviceFault", "DeviceTimeout", "MotionStalled", "ProtocolError"]


class DeviceError(RigError):
    """A device failed; ``device`` and ``operation`` say which and doing what."""

    def __init__(self, device: str, operation: str, detail: str):
        self.device = device
        self.operation = operation
        self.detail = detail
        super().__init__(f"{device}: {operation} failed: {detail}")


class DeviceTimeout(DeviceError):
    """No (valid) reply within the timeout, after all retries."""


class ProtocolError(DeviceError):
    """A reply arrived but was malformed (bad CRC, wrong length, wrong id)."""


class DeviceFault(DeviceError):
    """The device reports a hardware fault (overload, overheating, low battery…)."""


class MotionStalled(DeviceError):
    """An axis stopped short of its target."""
