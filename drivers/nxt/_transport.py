"""How NXT telegrams travel: USB bulk transfers (pyusb) or Bluetooth SPP (serial).

USB: the brick (vendor 0x0694, product 0x0002) has one interface with a bulk
OUT endpoint 0x01 and a bulk IN endpoint 0x82; a telegram is one transfer, with
no length prefix. Bluetooth: the serial-port profile carries each telegram
behind a 2-byte little-endian length. Both transports raise ``TimeoutError``
when no reply arrives in time and ``TelegramError(malformed=True)`` for a
truncated or oversized frame; the brick turns these into ``DeviceError``s.
"""

from __future__ import annotations

import contextlib
import logging
import struct
import termios
from collections.abc import Iterator
from typing import Protocol

import serial
import usb.core
import usb.util

from drivers._lock import serial_lock_key
from drivers.errors import DeviceError
from drivers.nxt._telegram import TelegramError

__all__ = ["NxtTransport", "SerialTransport", "UsbTransport"]

log = logging.getLogger(__name__)

USB_OUT_ENDPOINT = 0x01
USB_IN_ENDPOINT = 0x82
USB_INTERFACE = 0
MAX_TELEGRAM = 64  # a direct command or reply never exceeds 64 bytes


class NxtTransport(Protocol):
    """One link to a brick; ``name`` says which, for error messages; ``lock_key``
    names the device for the one-owner lock (``drivers._lock``)."""

    name: str
    lock_key: str

    def send(self, telegram: bytes, *, timeout_s: float) -> None: ...

    def receive(self, *, timeout_s: float) -> bytes: ...

    def discard_input(self) -> None: ...

    def close(self) -> None: ...


def _ms(timeout_s: float) -> int:
    return max(1, round(timeout_s * 1000))


class UsbTransport:
    """A brick on USB, found with ``usb.core.find``.

    ``backend`` is pyusb's: None picks libusb on a real machine; the simulator
    passes its fake brick backend, and everything else is the same code.
    """

    def __init__(self, *, vendor: int, product: int, backend=None):
        self.name = f"usb {vendor:04x}:{product:04x}"
        try:
            dev = usb.core.find(idVendor=vendor, idProduct=product, backend=backend)
        except usb.core.NoBackendError as err:
            raise DeviceError(
                self.name, "open", "pyusb finds no USB backend; install libusb-1.0"
            ) from err
        if dev is None:
            raise DeviceError(
                self.name,
                "open",
                "no NXT brick on USB; is it switched on, plugged in, and readable by this user?",
            )
        try:
            dev.set_configuration()
            usb.util.claim_interface(dev, USB_INTERFACE)
        except usb.core.USBError as err:
            usb.util.dispose_resources(dev)
            raise DeviceError(self.name, "open", f"cannot claim the interface: {err}") from err
        self._dev = dev
        self.lock_key = f"usb bus {dev.bus} address {dev.address}"

    def send(self, telegram: bytes, *, timeout_s: float) -> None:
        try:
            self._dev.write(USB_OUT_ENDPOINT, telegram, timeout=_ms(timeout_s))
        except usb.core.USBTimeoutError as err:
            raise TimeoutError(f"bulk write to {self.name} timed out after {timeout_s} s") from err
        except usb.core.USBError as err:
            raise ConnectionError(f"bulk write to {self.name} failed: {err}") from err

    def receive(self, *, timeout_s: float) -> bytes:
        try:
            data = self._dev.read(USB_IN_ENDPOINT, MAX_TELEGRAM, timeout=_ms(timeout_s))
        except usb.core.USBTimeoutError as err:
            raise TimeoutError(f"no reply from {self.name} within {timeout_s} s") from err
        except usb.core.USBError as err:
            raise ConnectionError(f"bulk read from {self.name} failed: {err}") from err
        return bytes(data)

    def discard_input(self) -> None:
        # A late reply to a request that timed out would answer the next one.
        while True:
            try:
                stale = self.receive(timeout_s=0.001)
            except TimeoutError:
                return
            log.debug("%s: discarded stale reply %s", self.name, stale.hex(" "))

    def close(self) -> None:
        try:
            usb.util.release_interface(self._dev, USB_INTERFACE)
        finally:
            usb.util.dispose_resources(self._dev)


class SerialTransport:
    """A brick over Bluetooth SPP (``/dev/rfcomm0``) or any serial port: a pty in the sim.

    A port that vanished (the brick switched off, the adapter pulled, the peer
    killed) fails in pyserial or in the tty layer below it (``termios.error``,
    ``OSError``); every operation turns these into ``ConnectionError`` naming
    the port, which the brick reports as a ``DeviceError``.
    """

    def __init__(self, port: str, *, baudrate: int = 115200):
        self.name = f"serial {port}"
        self.lock_key = serial_lock_key(port)
        try:
            self._port = serial.Serial(port, baudrate=baudrate, timeout=1.0, write_timeout=1.0)
        except serial.SerialException as err:
            raise DeviceError(self.name, "open", f"cannot open the serial port: {err}") from err

    def send(self, telegram: bytes, *, timeout_s: float) -> None:
        with self._port_errors("write to"):
            self._port.write_timeout = timeout_s
            try:
                self._port.write(struct.pack("<H", len(telegram)) + telegram)
                self._port.flush()
            except serial.SerialTimeoutException as err:
                raise TimeoutError(f"write to {self.name} timed out after {timeout_s} s") from err

    def receive(self, *, timeout_s: float) -> bytes:
        with self._port_errors("read from"):
            self._port.timeout = timeout_s
            prefix = self._port.read(2)
            if len(prefix) < 2:
                raise TimeoutError(f"no reply from {self.name} within {timeout_s} s")
            (length,) = struct.unpack("<H", prefix)
            if not 0 < length <= MAX_TELEGRAM:
                raise TelegramError(
                    f"length prefix {length} from {self.name} is outside 1..{MAX_TELEGRAM}",
                    malformed=True,
                )
            body = self._port.read(length)
        if len(body) < length:
            raise TelegramError(
                f"reply from {self.name} cut short: {len(body)} of {length} bytes",
                malformed=True,
            )
        return body

    def discard_input(self) -> None:
        with self._port_errors("flushing"):
            self._port.reset_input_buffer()

    def close(self) -> None:
        with self._port_errors("closing"):
            self._port.close()

    @contextlib.contextmanager
    def _port_errors(self, doing: str) -> Iterator[None]:
        try:
            yield
        except (serial.SerialException, termios.error, OSError) as err:
            if isinstance(err, TimeoutError | ConnectionError):
                raise
            raise ConnectionError(f"{doing} {self.name} failed: {_reason(err)}") from err


def _reason(err: Exception) -> str:
    """``termios.error`` carries ``(errno, text)`` as its args; say the text."""
    if isinstance(err, termios.error) and len(err.args) == 2:
        return f"{err.args[1]} (errno {err.args[0]})"
    return str(err)
