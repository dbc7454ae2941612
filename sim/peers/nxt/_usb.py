"""The fake NXT brick as a pyusb backend: ``usb.core.find(..., backend=...)`` finds it.

It implements ``usb.backend.IBackend`` for one device with the NXT's USB
identity (vendor 0x0694, product 0x0002): one configuration (value 1), one
interface (0, vendor class 0xFF) with a bulk OUT endpoint 0x01 and a bulk IN
endpoint 0x82, 64-byte packets. A bulk write hands the telegram to the brick;
its reply waits for the next bulk read. A read with nothing to return waits
out its timeout and raises ``usb.core.USBTimeoutError``, as libusb does.
"""

# ruff: noqa: N815  (descriptor field names are the USB specification's, as pyusb reads them)

from __future__ import annotations

import errno
import threading
import time
from collections import deque
from dataclasses import dataclass

import usb.backend
import usb.core

from sim.peers.nxt._brick import FakeNxtBrick

__all__ = ["FakeNxtUsbBackend"]

OUT_ENDPOINT = 0x01
IN_ENDPOINT = 0x82
_BULK = 0x02
_PACKET = 64
_LIBUSB_ERROR_TIMEOUT = -7
_LIBUSB_ERROR_INVALID_PARAM = -2


@dataclass(frozen=True)
class _DeviceDescriptor:
    idVendor: int
    idProduct: int
    bus: int
    address: int
    bLength: int = 18
    bDescriptorType: int = 0x01
    bcdUSB: int = 0x0200
    bDeviceClass: int = 0x00
    bDeviceSubClass: int = 0x00
    bDeviceProtocol: int = 0x00
    bMaxPacketSize0: int = 8
    bcdDevice: int = 0x0000
    iManufacturer: int = 0
    iProduct: int = 0
    iSerialNumber: int = 0
    bNumConfigurations: int = 1
    port_number: int = 1
    port_numbers: tuple[int, ...] = (1,)
    speed: int = 2  # full speed


@dataclass(frozen=True)
class _ConfigurationDescriptor:
    bLength: int = 9
    bDescriptorType: int = 0x02
    wTotalLength: int = 32
    bNumInterfaces: int = 1
    bConfigurationValue: int = 1
    iConfiguration: int = 0
    bmAttributes: int = 0xC0  # self powered
    bMaxPower: int = 0
    extra_descriptors: tuple = ()


@dataclass(frozen=True)
class _InterfaceDescriptor:
    bLength: int = 9
    bDescriptorType: int = 0x04
    bInterfaceNumber: int = 0
    bAlternateSetting: int = 0
    bNumEndpoints: int = 2
    bInterfaceClass: int = 0xFF
    bInterfaceSubClass: int = 0xFF
    bInterfaceProtocol: int = 0xFF
    iInterface: int = 0
    extra_descriptors: tuple = ()


@dataclass(frozen=True)
class _EndpointDescriptor:
    bEndpointAddress: int
    bLength: int = 7
    bDescriptorType: int = 0x05
    bmAttributes: int = _BULK
    wMaxPacketSize: int = _PACKET
    bInterval: int = 0
    bRefresh: int = 0
    bSynchAddress: int = 0
    extra_descriptors: tuple = ()


_ENDPOINTS = (_EndpointDescriptor(OUT_ENDPOINT), _EndpointDescriptor(IN_ENDPOINT))


class FakeNxtUsbBackend(usb.backend.IBackend):
    """A pyusb backend whose only device is ``brick``."""

    def __init__(
        self, brick: FakeNxtBrick, *, vendor: int = 0x0694, product: int = 0x0002, bus: int = 1
    ):
        self.brick = brick
        self._descriptor = _DeviceDescriptor(idVendor=vendor, idProduct=product, bus=bus, address=2)
        self._replies: deque[bytes] = deque()
        self._claimed: set[int] = set()
        self.open_handles = 0
        self._lock = threading.Lock()

    def _invalid(self, what: str) -> usb.core.USBError:
        return usb.core.USBError(f"fake NXT: {what}", _LIBUSB_ERROR_INVALID_PARAM, errno.EINVAL)

    def enumerate_devices(self):
        yield self._descriptor

    def get_device_descriptor(self, dev):
        return dev

    def get_configuration_descriptor(self, dev, config):
        if config != 0:
            raise IndexError(f"fake NXT has one configuration, not index {config}")
        return _ConfigurationDescriptor()

    def get_interface_descriptor(self, dev, intf, alt, config):
        if (intf, alt, config) != (0, 0, 0):
            raise IndexError(f"fake NXT has interface 0 alt 0 only, not {intf}/{alt}")
        return _InterfaceDescriptor()

    def get_endpoint_descriptor(self, dev, ep, intf, alt, config):
        return _ENDPOINTS[ep]

    def open_device(self, dev):
        with self._lock:
            self.open_handles += 1
        return dev

    def close_device(self, dev_handle):
        with self._lock:
            self.open_handles -= 1
            self._claimed.clear()
            self._replies.clear()

    def set_configuration(self, dev_handle, config_value):
        if config_value != 1:
            raise self._invalid(f"configuration {config_value} does not exist; valid is 1")

    def get_configuration(self, dev_handle):
        return 1

    def claim_interface(self, dev_handle, intf):
        if intf != 0:
            raise self._invalid(f"interface {intf} does not exist; valid is 0")
        self._claimed.add(intf)

    def release_interface(self, dev_handle, intf):
        self._claimed.discard(intf)

    def bulk_write(self, dev_handle, ep, intf, data, timeout):
        if ep != OUT_ENDPOINT or intf not in self._claimed:
            raise self._invalid(f"bulk write to endpoint 0x{ep:02x} of interface {intf}")
        reply = self.brick.handle(bytes(data))
        if reply is not None:
            with self._lock:
                self._replies.append(reply)
        return len(data)

    def bulk_read(self, dev_handle, ep, intf, buff, timeout):
        if ep != IN_ENDPOINT or intf not in self._claimed:
            raise self._invalid(f"bulk read from endpoint 0x{ep:02x} of interface {intf}")
        with self._lock:
            reply = self._replies.popleft() if self._replies else None
        if reply is None:
            time.sleep(timeout / 1000)
            raise usb.core.USBTimeoutError(
                "Operation timed out", _LIBUSB_ERROR_TIMEOUT, errno.ETIMEDOUT
            )
        n = min(len(buff), len(reply))
        buff[:n] = type(buff)(buff.typecode, reply[:n])
        return n
