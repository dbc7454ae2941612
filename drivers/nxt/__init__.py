"""LEGO NXT direct commands over USB or Bluetooth serial, and the laser unit they drive.

``open_device("laser", config.laser, clock=...)`` opens an ``NxtLaser`` (its
``tilt`` is an ``NxtTilt`` axis); ``NxtBrick`` speaks the direct commands; the
telegram functions are pure bytes in/out.
"""

from drivers.nxt._brick import NxtBrick, open_transport
from drivers.nxt._laser import NxtLaser
from drivers.nxt._telegram import (
    MOTOR_PORTS,
    Opcode,
    OutputMode,
    OutputState,
    RegulationMode,
    RunState,
    TelegramError,
    decode_battery_level,
    decode_output_state,
    decode_status,
    encode_get_battery_level,
    encode_get_output_state,
    encode_reset_motor_position,
    encode_set_output_state,
)
from drivers.nxt._tilt import NxtTilt
from drivers.nxt._transport import NxtTransport, SerialTransport, UsbTransport

__all__ = [
    "MOTOR_PORTS",
    "NxtBrick",
    "NxtLaser",
    "NxtTilt",
    "NxtTransport",
    "Opcode",
    "OutputMode",
    "OutputState",
    "RegulationMode",
    "RunState",
    "SerialTransport",
    "TelegramError",
    "UsbTransport",
    "decode_battery_level",
    "decode_output_state",
    "decode_status",
    "encode_get_battery_level",
    "encode_get_output_state",
    "encode_reset_motor_position",
    "encode_set_output_state",
    "open_transport",
]
