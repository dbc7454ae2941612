"""Device drivers, one family per module, each speaking its device's real protocol.

The same driver serves a lab's hardware and the simulator's peers: only the
connection in the rig config differs. Drivers are synchronous; time is an
injected ``rig.clock.Clock``.
"""

from drivers.camera import Camera, Frame, OpenCvCamera, SimCamera, open_camera
from drivers.dynamixel import DynamixelArc, DynamixelBus
from drivers.errors import DeviceError, DeviceFault, DeviceTimeout, MotionStalled, ProtocolError
from drivers.interfaces import Arc, LampBank, Turntable
from drivers.modbus import ModbusLampBank, ModbusTurntable
from drivers.nxt import NxtBrick, NxtLaser
from drivers.retry import with_retries

__all__ = [
    "Arc",
    "Camera",
    "DeviceError",
    "DeviceFault",
    "DeviceTimeout",
    "DynamixelArc",
    "DynamixelBus",
    "Frame",
    "LampBank",
    "ModbusLampBank",
    "ModbusTurntable",
    "MotionStalled",
    "NxtBrick",
    "NxtLaser",
    "OpenCvCamera",
    "ProtocolError",
    "SimCamera",
    "Turntable",
    "open_camera",
    "with_retries",
]
