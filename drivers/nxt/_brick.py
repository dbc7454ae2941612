"""An NXT brick spoken to with direct commands, over either transport."""

from __future__ import annotations

from collections.abc import Callable
from typing import TypeVar

from drivers._lock import DeviceLock
from drivers.errors import DeviceError, DeviceFault, DeviceTimeout, ProtocolError
from drivers.nxt._telegram import (
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
from drivers.nxt._transport import NxtTransport, SerialTransport, UsbTransport
from drivers.retry import with_retries
from rig.clock import Clock
from rig.devices import NxtLaserUnit, Retry

__all__ = ["NxtBrick", "open_transport"]

T = TypeVar("T")


def _status(opcode: Opcode) -> Callable[[bytes], None]:
    def check(reply: bytes) -> None:
        decode_status(reply, opcode)

    return check


def open_transport(connection: NxtLaserUnit, *, usb_backend=None) -> NxtTransport:
    """The transport ``connection.transport`` names (``usb_backend``: pyusb's, for USB)."""
    if connection.transport == "usb":
        return UsbTransport(
            vendor=connection.usb_vendor, product=connection.usb_product, backend=usb_backend
        )
    return SerialTransport(connection.serial_port)


class NxtBrick:
    """Direct commands with a reply, each with timeout and bounded retries.

    Every public method is one request/reply exchange; a garbled reply or none
    in ``retry.timeout_s`` is retried ``retry.retries`` times with backoff, then
    raises ``DeviceTimeout`` / ``ProtocolError`` naming the brick and command.
    A reply with an error status raises ``DeviceFault`` at once. The brick
    holds the device lock of its transport until ``close``; a brick another
    process holds is refused (the transport is closed again).
    """

    def __init__(self, transport: NxtTransport, *, retry: Retry, clock: Clock, device: str):
        self.transport = transport
        self.retry = retry
        self.clock = clock
        self.device = f"{device} ({transport.name})"
        try:
            self._lock = DeviceLock(f"nxt {transport.lock_key}", device=self.device)
        except DeviceError:
            transport.close()
            raise

    @classmethod
    def open(
        cls, connection: NxtLaserUnit, *, clock: Clock, device: str = "NXT brick", usb_backend=None
    ) -> NxtBrick:
        """Open the transport ``connection`` names; errors name ``device`` and the link."""
        try:
            transport = open_transport(connection, usb_backend=usb_backend)
        except DeviceError as err:
            raise type(err)(f"{device} ({err.device})", err.operation, err.detail) from err
        return cls(transport, retry=connection.retry, clock=clock, device=device)

    def request(
        self, telegram: bytes, opcode: Opcode, decode: Callable[[bytes], T], *, retried: bool = True
    ) -> T:
        """Send one telegram and decode its reply, with the connection's retries.

        ``retried=False`` makes one attempt only, for a caller that retries a
        larger step itself (a move re-reads the position before re-sending).
        """

        def attempt() -> T:
            try:
                self.transport.discard_input()
                self.transport.send(telegram, timeout_s=self.retry.timeout_s)
                return decode(self.transport.receive(timeout_s=self.retry.timeout_s))
            except TimeoutError as err:
                raise DeviceTimeout(self.device, opcode.name, str(err)) from err
            except ConnectionError as err:
                raise DeviceError(self.device, opcode.name, str(err)) from err
            except TelegramError as err:
                if err.malformed:
                    raise ProtocolError(self.device, opcode.name, str(err)) from err
                raise DeviceFault(self.device, opcode.name, str(err)) from err

        if not retried:
            return attempt()
        return with_retries(
            attempt, retry=self.retry, clock=self.clock, device=self.device, operation=opcode.name
        )

    def set_output_state(
        self,
        port: int,
        *,
        power: int,
        mode: OutputMode,
        regulation: RegulationMode,
        run_state: RunState,
        tacho_limit: int = 0,
        turn_ratio: int = 0,
        retried: bool = True,
    ) -> None:
        """SETOUTPUTSTATE on one port (``tacho_limit`` in motor degrees, 0: no limit)."""
        try:
            telegram = encode_set_output_state(
                port,
                power=power,
                mode=mode,
                regulation=regulation,
                turn_ratio=turn_ratio,
                run_state=run_state,
                tacho_limit=tacho_limit,
            )
        except TelegramError as err:
            raise DeviceError(self.device, "SET_OUTPUT_STATE", str(err)) from err
        self.request(
            telegram, Opcode.SET_OUTPUT_STATE, _status(Opcode.SET_OUTPUT_STATE), retried=retried
        )

    def get_output_state(self, port: int, *, retried: bool = True) -> OutputState:
        """GETOUTPUTSTATE: power, mode, run state and the three tacho counters of a port."""
        return self.request(
            encode_get_output_state(port),
            Opcode.GET_OUTPUT_STATE,
            decode_output_state,
            retried=retried,
        )

    def reset_motor_position(self, port: int, *, relative: bool) -> None:
        """RESETMOTORPOSITION: zero the block tacho count (relative) or the rotation count."""
        telegram = encode_reset_motor_position(port, relative=relative)
        self.request(telegram, Opcode.RESET_MOTOR_POSITION, _status(Opcode.RESET_MOTOR_POSITION))

    def battery_level_mv(self) -> int:
        """GETBATTERYLEVEL: the battery voltage in millivolts."""
        return self.request(
            encode_get_battery_level(), Opcode.GET_BATTERY_LEVEL, decode_battery_level
        )

    def close(self) -> None:
        """Close the transport and release the device; idempotent."""
        try:
            self.transport.close()
        finally:
            self._lock.release()
