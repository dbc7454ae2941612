"""Dynamixel Protocol 2.0 servos (X series) through dynamixel-sdk: the light arc."""

from drivers.dynamixel._bus import HARDWARE_ERRORS, DynamixelBus, describe_hardware_error
from drivers.dynamixel.arc import DynamixelArc, X, deg_to_ticks, ticks_to_deg

__all__ = [
    "HARDWARE_ERRORS",
    "DynamixelArc",
    "DynamixelBus",
    "X",
    "deg_to_ticks",
    "describe_hardware_error",
    "ticks_to_deg",
]
