"""Device drivers, one family per package, each speaking its device's real protocol.

The same driver serves a lab's hardware and the simulator's peers: only the
connection in the rig config differs. ``open_device(role, section, clock=...)``
opens the driver that the section's ``kind`` names (``drivers.registry``).
Drivers are synchronous; time is an injected ``rig.clock.Clock``.
"""

from drivers.camera import Camera, Frame, OpenCvCamera, SimCamera
from drivers.dynamixel import DynamixelArc, DynamixelBus
from drivers.errors import DeviceError, DeviceFault, DeviceTimeout, MotionStalled, ProtocolError
from drivers.interfaces import Axis, LampBank, LaserUnit, Positioner
from drivers.modbus import ModbusLampBank, ModbusTurntable
from drivers.nxt import NxtBrick, NxtLaser, NxtTilt
from drivers.registry import open_device, register
from drivers.retry import with_retries
from drivers.ur import UrArm

__all__ = [
    "Axis",
    "Camera",
    "DeviceError",
    "DeviceFault",
    "DeviceTimeout",
    "DynamixelArc",
    "DynamixelBus",
    "Frame",
    "LampBank",
    "LaserUnit",
    "ModbusLampBank",
    "ModbusTurntable",
    "MotionStalled",
    "NxtBrick",
    "NxtLaser",
    "NxtTilt",
    "OpenCvCamera",
    "Positioner",
    "ProtocolError",
    "SimCamera",
    "UrArm",
    "open_device",
    "register",
    "with_retries",
]
