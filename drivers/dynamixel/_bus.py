"""A Dynamixel Protocol 2.0 bus through dynamixel-sdk, with timeouts, retries, clear errors.

``DynamixelBus`` opens the serial port (a USB adapter's ``/dev/ttyUSB0`` or
the simulator's pty: same code) and turns the SDK's result codes and status
error bytes into ``drivers.errors``: no reply → ``DeviceTimeout``, a reply
failing its CRC → ``ProtocolError`` (both retried), the alert bit →
``DeviceFault`` naming the servo and its hardware error bits, any other
status error → ``DeviceError`` (a wrong address, a value beyond a limit).
"""

from __future__ import annotations

import logging
import termios
from collections.abc import Callable, Mapping
from typing import TypeVar

import dynamixel_sdk as sdk
import serial

from drivers._lock import DeviceLock, serial_lock_key
from drivers.errors import DeviceError, DeviceFault, DeviceTimeout, ProtocolError
from drivers.retry import with_retries
from rig.clock import Clock
from rig.devices import DynamixelServos

__all__ = ["HARDWARE_ERRORS", "DynamixelBus"]

log = logging.getLogger(__name__)
T = TypeVar("T")

HARDWARE_ERROR_STATUS = 70
HARDWARE_ERRORS = {
    0: "input voltage error",
    2: "overheating",
    3: "motor encoder error",
    4: "electrical shock",
    5: "overload",
}
_STATUS_ERRORS = {
    1: "result fail",
    2: "instruction error",
    3: "CRC error (the servo got a damaged instruction)",
    4: "data range error",
    5: "data length error",
    6: "data limit error (value beyond the servo's limits)",
    7: "access error (read-only item, or EEPROM while torque is on)",
}
_ALERT = 0x80


#: How long one read of the port waits for the bytes it asks for, seconds.
_READ_WAIT_S = 0.002


class _Port(sdk.PortHandler):
    """The SDK's port with our reply timeout instead of its fixed ~34 ms, and reads that
    wait for their bytes."""

    def __init__(self, port_name: str, timeout_s: float):
        super().__init__(port_name)
        self._timeout_ms = 1000.0 * timeout_s

    def setPacketTimeout(self, packet_length):  # noqa: N802 (SDK API)
        super().setPacketTimeout(packet_length)
        self.packet_timeout = max(self.packet_timeout, self._timeout_ms)

    def setupPort(self, cflag_baud):  # noqa: N802 (SDK API)
        # The SDK opens the port non-blocking and reads it in a loop until the reply
        # timeout: a spin of ~100 000 empty reads a second, most of a simulated
        # session's CPU. A read that waits a little for its bytes checks the
        # timeout as often as it needs to be checked.
        opened = super().setupPort(cflag_baud)
        self.ser.timeout = _READ_WAIT_S
        return opened


def describe_hardware_error(bits: int) -> str:
    """Names of the set hardware-error bits, e.g. ``'overload, overheating'``."""
    names = [name for bit, name in HARDWARE_ERRORS.items() if bits >> bit & 1]
    return ", ".join(names) or f"unknown bits 0x{bits:02x}"


class DynamixelBus:
    """Servos on one serial bus.

    Parameters
    ----------
    connection : DynamixelServos
        Serial port, baud rate, per-request timeout and retries.
    device : str
        Name in error messages (``"light arc"``).
    clock : Clock
        Time for the backoff between retries.
    """

    def __init__(self, connection: DynamixelServos, *, device: str, clock: Clock):
        self.connection = connection
        self.device = device
        self._clock = clock
        self._lock = DeviceLock(
            f"dynamixel {serial_lock_key(connection.serial_port)}", device=device
        )
        self.port = _Port(connection.serial_port, connection.retry.timeout_s)
        self.packets = sdk.PacketHandler(2.0)
        try:
            opened = self.port.setBaudRate(connection.baudrate)
        except (serial.SerialException, OSError) as err:
            self._lock.release()
            raise DeviceError(
                device, "open", f"cannot open serial port {connection.serial_port!r}: {err}"
            ) from err
        if not opened:
            self.close()
            raise DeviceError(
                device, "open", f"baud rate {connection.baudrate} is not supported by the SDK"
            )

    # -- single-servo access -----------------------------------------------------
    def ping(self, servo_id: int) -> int:
        """The servo's model number."""
        return self._txrx(servo_id, "ping", lambda: self.packets.ping(self.port, servo_id))

    def read(self, servo_id: int, address: int, size: int, *, operation: str) -> int:
        """Read an item of ``size`` (1, 2 or 4) bytes; 4-byte items are signed."""
        read = {
            1: self.packets.read1ByteTxRx,
            2: self.packets.read2ByteTxRx,
            4: self.packets.read4ByteTxRx,
        }[size]
        value = self._txrx(servo_id, operation, lambda: read(self.port, servo_id, address))
        return _signed(value, size)

    def write(self, servo_id: int, address: int, size: int, value: int, *, operation: str) -> None:
        """Write an item of ``size`` bytes and check the servo's status reply."""
        write = {
            1: self.packets.write1ByteTxRx,
            2: self.packets.write2ByteTxRx,
            4: self.packets.write4ByteTxRx,
        }[size]
        raw = value & ((1 << 8 * size) - 1)

        def attempt():
            result, error = write(self.port, servo_id, address, raw)
            return None, result, error

        self._txrx(servo_id, operation, attempt)

    def reboot(self, servo_id: int) -> None:
        """REBOOT: clears a hardware error; torque comes back off."""
        self._txrx(servo_id, "reboot", lambda: (None, *self.packets.reboot(self.port, servo_id)))

    # -- several servos at once --------------------------------------------------------
    def sync_write(
        self, address: int, size: int, values: Mapping[int, int], *, operation: str
    ) -> None:
        """One SYNC_WRITE of ``values`` (servo id → value); servos do not reply."""
        group = sdk.GroupSyncWrite(self.port, self.packets, address, size)
        for servo_id, value in values.items():
            raw = (value & ((1 << 8 * size) - 1)).to_bytes(size, "little")
            group.addParam(servo_id, list(raw))

        def attempt() -> None:
            result = group.txPacket()
            if result != sdk.COMM_SUCCESS:
                raise DeviceTimeout(
                    self.device, operation, f"sync write: {self.packets.getTxRxResult(result)}"
                )

        self._retried(attempt, operation)

    def sync_read(
        self, address: int, size: int, ids: tuple[int, ...], *, operation: str
    ) -> dict[int, bytes]:
        """One SYNC_READ of ``size`` bytes at ``address`` from each servo: id → raw bytes."""
        group = sdk.GroupSyncRead(self.port, self.packets, address, size)
        for servo_id in ids:
            group.addParam(servo_id)

        def attempt() -> dict[int, bytes]:
            result = group.txRxPacket()
            if result != sdk.COMM_SUCCESS:
                raise _comm_error(self.device, operation, result, self.packets, ids)
            return {i: bytes(group.data_dict[i]) for i in ids}

        return self._retried(attempt, operation)

    def close(self) -> None:
        """Close the serial port and release the device; idempotent."""
        try:
            if self.port.is_open:
                self.port.closePort()
        finally:
            self._lock.release()

    # -- one transaction, retried --------------------------------------------------------
    def _retried(self, attempt: Callable[[], T], operation: str) -> T:
        """``attempt`` under the connection's retries; the serial port failing beneath the
        SDK (adapter unplugged, pty gone: termios/OS errors) is a ``DeviceError`` naming
        the port, not retried."""

        def guarded() -> T:
            try:
                return attempt()
            except (serial.SerialException, OSError, termios.error) as err:
                raise DeviceError(
                    self.device,
                    operation,
                    f"serial port {self.connection.serial_port!r} failed: {err}",
                ) from err

        return with_retries(
            guarded,
            retry=self.connection.retry,
            clock=self._clock,
            device=self.device,
            operation=operation,
        )

    def _txrx(self, servo_id: int, operation: str, send: Callable[[], tuple]) -> T:
        def attempt():
            value, result, error = send()
            if result != sdk.COMM_SUCCESS:
                raise _comm_error(self.device, operation, result, self.packets, (servo_id,))
            if error & _ALERT:
                self._raise_hardware_error(servo_id, operation)
            if error & ~_ALERT == 3:
                raise ProtocolError(
                    self.device, operation, f"servo {servo_id}: {_STATUS_ERRORS[3]}"
                )
            if error & ~_ALERT:
                code = error & ~_ALERT
                raise DeviceError(
                    self.device,
                    operation,
                    f"servo {servo_id} answered error {code}: "
                    f"{_STATUS_ERRORS.get(code, 'unknown')}",
                )
            return value

        return self._retried(attempt, operation)

    def _raise_hardware_error(self, servo_id: int, operation: str) -> None:
        bits, result, _ = self.packets.read1ByteTxRx(self.port, servo_id, HARDWARE_ERROR_STATUS)
        detail = (
            f"0x{bits:02x} ({describe_hardware_error(bits)})"
            if result == sdk.COMM_SUCCESS
            else "unreadable"
        )
        raise DeviceFault(
            self.device,
            operation,
            f"servo {servo_id} reports hardware error {detail}; torque is off until a reboot",
        )


def _comm_error(device: str, operation: str, result: int, packets, ids) -> DeviceError:
    text = packets.getTxRxResult(result)
    who = f"servo {ids[0]}" if len(ids) == 1 else f"servos {list(ids)}"
    if result == sdk.COMM_RX_CORRUPT:
        return ProtocolError(device, operation, f"{who}: corrupt status packet ({text})")
    return DeviceTimeout(device, operation, f"{who}: no status packet ({text})")


def _signed(value: int, size: int) -> int:
    if size == 4 and value >= 1 << 31:
        return value - (1 << 32)
    return value
