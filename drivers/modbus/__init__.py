"""Modbus devices (TCP or RTU): the turntable's stepper drive and the lamp bank."""

from drivers.modbus._link import ModbusLink
from drivers.modbus.lamps import ModbusLampBank
from drivers.modbus.turntable import DriveStatus, ModbusTurntable

__all__ = ["DriveStatus", "ModbusLampBank", "ModbusLink", "ModbusTurntable"]
