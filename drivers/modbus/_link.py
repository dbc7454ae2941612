"""One Modbus client, TCP or RTU, with timeouts, bounded retries and clear errors.

The transport is chosen by ``ModbusConnection.protocol``: ``tcp`` talks to
``host:port``, ``rtu`` to ``serial_port`` (a ``/dev/ttyUSB0`` on a rig, a pty in
the simulator) — the same code either way. pymodbus's own retries are off:
retries and backoff run here, on the injected clock, so a stubborn device
fails after ``retry.retries`` extra tries with one error naming it.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence
from typing import Literal, TypeVar

from pymodbus import FramerType
from pymodbus.client import ModbusSerialClient, ModbusTcpClient
from pymodbus.constants import ExcCodes
from pymodbus.exceptions import ConnectionException, ModbusException, ModbusIOException
from pymodbus.pdu import ModbusPDU

from drivers._lock import DeviceLock, serial_lock_key
from drivers.errors import DeviceError, DeviceTimeout, ProtocolError
from drivers.retry import with_retries
from rig.clock import Clock
from rig.devices import ModbusConnection

__all__ = ["ModbusLink"]

log = logging.getLogger(__name__)
T = TypeVar("T")
_INT32 = ModbusTcpClient.DATATYPE.INT32


class ModbusLink:
    """A Modbus master for one device (unit id) on a TCP or RTU connection.

    Parameters
    ----------
    connection : ModbusConnection
        Where the device is and how long to wait (``retry.timeout_s`` per
        request, ``retry.retries`` extra tries, ``retry.backoff_s`` doubling).
    device : str
        The device's name in error messages (``"turntable"``).
    clock : Clock
        Time for the backoff between tries.

    The link holds the device lock of its connection and unit id (two
    daemons cannot drive one device) until ``close``.
    """

    def __init__(self, connection: ModbusConnection, *, device: str, clock: Clock):
        self.connection = connection
        self.device = device
        self._clock = clock
        timeout = connection.retry.timeout_s
        if connection.protocol == "tcp":
            self.where = f"tcp://{connection.host}:{connection.port}"
            self._client: ModbusTcpClient | ModbusSerialClient = ModbusTcpClient(
                connection.host, port=connection.port, timeout=timeout, retries=0
            )
            place = self.where
        else:
            self.where = f"rtu:{connection.serial_port}@{connection.baudrate}"
            self._client = ModbusSerialClient(
                str(connection.serial_port),
                framer=FramerType.RTU,
                baudrate=connection.baudrate,
                timeout=timeout,
                retries=0,
            )
            place = serial_lock_key(str(connection.serial_port))
        # pymodbus connects on the first request: nothing to undo if the lock is refused
        self._lock = DeviceLock(f"modbus {place} unit {connection.unit_id}", device=device)

    # -- registers ---------------------------------------------------------
    def read_holding(self, address: int, count: int, *, operation: str) -> list[int]:
        """Read ``count`` holding registers from ``address``."""
        what = f"read {count} holding register(s) at {address}"

        def read(dev: int) -> ModbusPDU:
            reply = self._client.read_holding_registers(address, count=count, device_id=dev)
            if not reply.isError() and len(reply.registers) != count:
                # RTU replies carry no transaction id: a reply that came after an earlier
                # request timed out answers that request, not this one (retried).
                raise ModbusException(
                    f"a reply of {len(reply.registers)} register(s) does not answer it "
                    "(a late reply to an earlier request?)"
                )
            return reply

        return list(self._request(operation, what, read).registers)

    def write_holding(self, address: int, values: Sequence[int], *, operation: str) -> None:
        """Write holding registers from ``address`` (function 16)."""
        self._request(
            operation,
            f"write {list(values)} to holding register(s) at {address}",
            lambda dev: self._client.write_registers(address, list(values), device_id=dev),
        )

    def read_int32(
        self, address: int, *, word_order: Literal["big", "little"], operation: str
    ) -> int:
        """Read a signed 32-bit value from two holding registers."""
        words = self.read_holding(address, 2, operation=operation)
        return int(self._client.convert_from_registers(words, _INT32, word_order=word_order))

    def write_int32(
        self, address: int, value: int, *, word_order: Literal["big", "little"], operation: str
    ) -> None:
        """Write a signed 32-bit value to two holding registers."""
        if not -(2**31) <= value < 2**31:
            raise ValueError(f"{self.device}: {operation}: {value} does not fit a signed 32-bit")
        words = self._client.convert_to_registers(value, _INT32, word_order=word_order)
        self.write_holding(address, words, operation=operation)

    # -- bits --------------------------------------------------------------
    def read_coils(self, address: int, count: int, *, operation: str) -> list[bool]:
        """Read ``count`` coils from ``address``."""
        reply = self._request(
            operation,
            f"read {count} coil(s) at {address}",
            lambda dev: self._client.read_coils(address, count=count, device_id=dev),
        )
        return [bool(b) for b in reply.bits[:count]]

    def write_coils(self, address: int, values: Sequence[bool], *, operation: str) -> None:
        """Write coils from ``address`` (function 15)."""
        self._request(
            operation,
            f"write {[int(v) for v in values]} to coil(s) at {address}",
            lambda dev: self._client.write_coils(address, list(values), device_id=dev),
        )

    def read_discrete_inputs(self, address: int, count: int, *, operation: str) -> list[bool]:
        """Read ``count`` discrete inputs from ``address``."""
        reply = self._request(
            operation,
            f"read {count} discrete input(s) at {address}",
            lambda dev: self._client.read_discrete_inputs(address, count=count, device_id=dev),
        )
        return [bool(b) for b in reply.bits[:count]]

    def close(self) -> None:
        """Close the socket or serial port and release the device; idempotent."""
        try:
            self._client.close()
        finally:
            self._lock.release()

    # -- one request, retried ------------------------------------------------
    def _request(self, operation: str, what: str, send: Callable[[int], ModbusPDU]) -> ModbusPDU:
        unit = self.connection.unit_id

        def attempt() -> ModbusPDU:
            try:
                reply = send(unit)
            except ConnectionException as err:
                raise DeviceTimeout(
                    self.device, operation, f"cannot reach {self.where} to {what}"
                ) from err
            except ModbusIOException as err:
                # A garbled RTU frame fails its CRC and is dropped by the framer,
                # so it too ends here: no valid reply within the timeout.
                raise DeviceTimeout(
                    self.device,
                    operation,
                    f"no valid reply from {self.where} (unit {unit}) within "
                    f"{self.connection.retry.timeout_s} s to {what}",
                ) from err
            except ModbusException as err:
                raise ProtocolError(self.device, operation, f"{what}: {err}") from err
            except OSError as err:  # the peer vanished mid-request (reset, broken pipe)
                raise DeviceTimeout(
                    self.device, operation, f"lost {self.where} while trying to {what}: {err}"
                ) from err
            if reply.isError():
                code = getattr(reply, "exception_code", None)
                raise DeviceError(self.device, operation, _refusal(what, code))
            return reply

        return with_retries(
            attempt,
            retry=self.connection.retry,
            clock=self._clock,
            device=self.device,
            operation=operation,
        )


def _refusal(what: str, code: int | None) -> str:
    try:
        name = ExcCodes(code).name if code is not None else "unknown"
    except ValueError:
        name = "unknown"
    hint = {
        ExcCodes.ILLEGAL_ADDRESS: "; check the register map in the rig config",
        ExcCodes.ILLEGAL_VALUE: "; the device rejects this value",
        ExcCodes.ILLEGAL_FUNCTION: "; the device does not support this function",
    }.get(code, "")
    return f"the device refused to {what}: exception {code} ({name}){hint}"
