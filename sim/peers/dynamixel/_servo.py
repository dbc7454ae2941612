"""One simulated X-series servo: its control table, tied to an axis of the world.

The subset of the X-series control table (e.g. XM430-W350) a rig uses;
addresses and sizes from the ROBOTIS e-manual. EEPROM items (below 64) can
be written only while torque is off; the read-only items answer from the
world: present position is the axis position in ticks, moving is 1 while the
axis moves. A hardware error (address 70) sets the alert bit of every status
packet and switches torque off, as the real servo's shutdown does.
"""

from __future__ import annotations

from rig.devices import DynamixelServos
from sim.world import World

__all__ = ["HARDWARE_ERRORS", "SimServo", "Table"]


class Table:
    """Control-table addresses (X-series)."""

    MODEL_NUMBER = 0  # 2 bytes, R
    FIRMWARE_VERSION = 6  # 1, R
    ID = 7  # 1, RW (EEPROM)
    BAUD_RATE = 8  # 1, RW (EEPROM)
    OPERATING_MODE = 11  # 1, RW (EEPROM): 3 position, 4 extended position
    MAX_POSITION_LIMIT = 48  # 4, RW (EEPROM)
    MIN_POSITION_LIMIT = 52  # 4, RW (EEPROM)
    TORQUE_ENABLE = 64  # 1, RW
    LED = 65  # 1, RW
    STATUS_RETURN_LEVEL = 68  # 1, RW
    HARDWARE_ERROR_STATUS = 70  # 1, R
    PROFILE_ACCELERATION = 108  # 4, RW
    PROFILE_VELOCITY = 112  # 4, RW
    GOAL_POSITION = 116  # 4, RW
    REALTIME_TICK = 120  # 2, R
    MOVING = 122  # 1, R
    MOVING_STATUS = 123  # 1, R
    PRESENT_POSITION = 132  # 4, R
    PRESENT_INPUT_VOLTAGE = 144  # 2, R
    PRESENT_TEMPERATURE = 146  # 1, R
    SIZE = 147


HARDWARE_ERRORS = {
    0: "input voltage error",
    2: "overheating",
    3: "motor encoder error",
    4: "electrical shock",
    5: "overload",
}
_EXTENDED_RANGE = 1_048_575  # ±256 turns in extended position mode
_WRITABLE_RAM = [(64, 66), (68, 69), (108, 120)]  # [start, end) of writable RAM items


class _Error:
    """Protocol 2.0 error numbers a servo answers with."""

    DATA_RANGE = 4
    DATA_LIMIT = 6
    ACCESS = 7


class SimServo:
    """A servo on the simulated bus, driving ``axis`` of ``world`` through ``gearing``.

    Ticks and axis degrees are related as the config describes the servos
    (written here from that description, not taken from the driver):
    ``ticks = zero_tick + deg / 360 * gear_ratio * ticks_per_rev``.
    """

    def __init__(
        self,
        servo_id: int,
        world: World,
        *,
        gearing: DynamixelServos,
        axis: str = "arc",
        model_number: int = 1020,
        operating_mode: int = 4,
    ):
        self.servo_id = servo_id
        self.world = world
        self.gearing = gearing
        self.axis = axis
        self.table = bytearray(Table.SIZE)
        self._put(Table.MODEL_NUMBER, 2, model_number)
        self._put(Table.FIRMWARE_VERSION, 1, 46)
        self._put(Table.ID, 1, servo_id)
        self._put(Table.BAUD_RATE, 1, 1)  # 57600 bps
        self._put(Table.OPERATING_MODE, 1, operating_mode)
        self._put(Table.MAX_POSITION_LIMIT, 4, 4095)
        self._put(Table.MIN_POSITION_LIMIT, 4, 0)
        self._put(Table.STATUS_RETURN_LEVEL, 1, 2)
        self._put(Table.GOAL_POSITION, 4, self._ticks(world.position(axis)))
        self._put(Table.PRESENT_INPUT_VOLTAGE, 2, 120)  # 12.0 V
        self._put(Table.PRESENT_TEMPERATURE, 1, 32)

    # -- state --------------------------------------------------------------
    @property
    def hardware_error(self) -> int:
        return self.table[Table.HARDWARE_ERROR_STATUS]

    def alert(self) -> int:
        """The alert bit (0x80) of this servo's status packets."""
        return 0x80 if self.hardware_error else 0

    def set_hardware_error(self, bits: int) -> None:
        """Inject a hardware error (bits of ``HARDWARE_ERRORS``); 0 clears it.

        Like the real shutdown, an error switches torque off and the axis stops.
        """
        if not 0 <= bits <= 0xFF:
            raise ValueError(f"servo {self.servo_id}: hardware error bits {bits} outside 0..255")
        self.table[Table.HARDWARE_ERROR_STATUS] = bits
        if bits:
            self.table[Table.TORQUE_ENABLE] = 0
            self.world.move(self.axis, self.world.position(self.axis))

    def reboot(self) -> None:
        """REBOOT: clear the hardware error, torque off."""
        self.table[Table.HARDWARE_ERROR_STATUS] = 0
        self.table[Table.TORQUE_ENABLE] = 0

    # -- READ / WRITE -------------------------------------------------------
    def read(self, address: int, length: int) -> tuple[int, bytes]:
        """(error number, data) of a READ of ``length`` bytes at ``address``."""
        if length < 1 or address + length > Table.SIZE:
            return _Error.DATA_RANGE, b""
        self._refresh()
        return 0, bytes(self.table[address : address + length])

    def write(self, address: int, data: bytes) -> int:
        """Apply a WRITE; returns the error number (0: done)."""
        end = address + len(data)
        if not data or end > Table.SIZE:
            return _Error.DATA_RANGE
        torque_on = self.table[Table.TORQUE_ENABLE] == 1
        eeprom = end <= Table.TORQUE_ENABLE and address >= Table.ID
        ram = any(lo <= address and end <= hi for lo, hi in _WRITABLE_RAM)
        if not (eeprom or ram) or (eeprom and torque_on):
            return _Error.ACCESS
        if _overlaps(address, end, Table.GOAL_POSITION, 4):
            if address != Table.GOAL_POSITION or len(data) < 4:
                return _Error.DATA_RANGE  # goal position is written whole
            goal = int.from_bytes(data[:4], "little", signed=True)
            if not self._goal_in_limits(goal):
                return _Error.DATA_LIMIT
        if _overlaps(address, end, Table.TORQUE_ENABLE, 1) and self.hardware_error:
            value = data[Table.TORQUE_ENABLE - address]
            if value:
                return _Error.ACCESS  # torque stays off until a REBOOT clears the error
        self.table[address:end] = data
        if not torque_on and self.table[Table.TORQUE_ENABLE] == 1:
            # torque on: the servo holds where it is (goal := present position)
            self._put(Table.GOAL_POSITION, 4, self._ticks(self.world.position(self.axis)))
        elif _overlaps(address, end, Table.GOAL_POSITION, 4):
            self._follow_goal()
        return 0

    # -- internals ----------------------------------------------------------
    def _goal_in_limits(self, goal: int) -> bool:
        if self.table[Table.OPERATING_MODE] == 4:
            return -_EXTENDED_RANGE <= goal <= _EXTENDED_RANGE
        low = self._get(Table.MIN_POSITION_LIMIT, 4)
        high = self._get(Table.MAX_POSITION_LIMIT, 4)
        return low <= goal <= high

    def _follow_goal(self) -> None:
        if self.table[Table.TORQUE_ENABLE] != 1:
            return
        goal = self._get(Table.GOAL_POSITION, 4)
        self.world.move(self.axis, self._deg(goal))

    def _refresh(self) -> None:
        moving = self.world.is_moving(self.axis)
        ticks = self._ticks(self.world.position(self.axis))
        self._put(Table.PRESENT_POSITION, 4, ticks)
        self._put(Table.MOVING, 1, int(moving))
        # moving status: bit 0 in-position, bit 1 profile ongoing
        in_position = abs(ticks - self._get(Table.GOAL_POSITION, 4)) <= 1 and not moving
        self._put(Table.MOVING_STATUS, 1, int(in_position) | int(moving) << 1)
        self._put(Table.REALTIME_TICK, 2, int(self.world.clock.now() * 1000) % 32768)

    def _ticks(self, axis_deg: float) -> int:
        g = self.gearing
        return g.zero_tick + round(axis_deg / 360.0 * g.gear_ratio * g.ticks_per_rev)

    def _deg(self, ticks: int) -> float:
        g = self.gearing
        return (ticks - g.zero_tick) * 360.0 / (g.ticks_per_rev * g.gear_ratio)

    def _put(self, address: int, size: int, value: int) -> None:
        self.table[address : address + size] = int(value).to_bytes(size, "little", signed=value < 0)

    def _get(self, address: int, size: int) -> int:
        return int.from_bytes(self.table[address : address + size], "little", signed=size == 4)


def _overlaps(start: int, end: int, item: int, size: int) -> bool:
    return start < item + size and item < end
