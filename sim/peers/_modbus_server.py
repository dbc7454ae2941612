"""A pymodbus server (TCP or RTU on a pty) in its own thread, with reply faults.

The device logic is a ``pymodbus.simulator.SimDevice`` whose ``action``
callback sees every request; this module only runs the server: an asyncio loop
in a thread, the listening socket or serial port, and a ``trace_packet`` hook
that drops or garbles replies as ``ReplyFaults`` decides.
"""

from __future__ import annotations

import asyncio
import logging
import threading
from concurrent.futures import Future
from typing import Literal

from pymodbus import FramerType
from pymodbus.server import ModbusSerialServer, ModbusTcpServer
from pymodbus.simulator import SimDevice

from sim.peers._faults import ReplyFaults
from sim.peers._pty import PtyNullModem

__all__ = ["ModbusServerThread"]

log = logging.getLogger(__name__)
_START_TIMEOUT_S = 10.0


class ModbusServerThread:
    """Serve one ``SimDevice`` over Modbus TCP (loopback) or RTU (a pty pair).

    Parameters
    ----------
    device : SimDevice
        Registers and the action callback of the simulated device.
    transport : "tcp" or "rtu"
        TCP listens on ``host:port`` (``port=0``: an ephemeral port); RTU serves
        one end of a pty null modem and leaves the other, ``serial_port``, to
        the driver.
    faults : ReplyFaults
        Consulted for every reply sent.
    """

    def __init__(
        self,
        device: SimDevice,
        *,
        name: str,
        transport: Literal["tcp", "rtu"] = "tcp",
        host: str = "127.0.0.1",
        port: int = 0,
        baudrate: int = 115200,
        faults: ReplyFaults,
    ):
        self.name = name
        self.transport = transport
        self.host = host
        self.port = port
        self.baudrate = baudrate
        self.serial_port: str | None = None
        self.faults = faults
        self._held = b""  # a late reply, sent before the next one
        self._device = device
        self._modem: PtyNullModem | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._server: ModbusTcpServer | ModbusSerialServer | None = None
        self._ready: Future[None] = Future()
        self._thread = threading.Thread(target=self._run, name=f"{name}-modbus", daemon=True)

    def start(self) -> ModbusServerThread:
        """Start serving; returns once the port is open (``port``/``serial_port`` set)."""
        if self.transport == "rtu":
            self._modem = PtyNullModem(f"{self.name}-pty").start()
            self.serial_port = self._modem.port_b
        self._thread.start()
        try:
            self._ready.result(timeout=_START_TIMEOUT_S)
        except BaseException:
            self.stop()
            raise
        return self

    def stop(self) -> None:
        """Close the server and every connection, join the thread; idempotent."""
        loop, server = self._loop, self._server
        if loop is not None and server is not None and self._thread.is_alive():
            asyncio.run_coroutine_threadsafe(server.shutdown(), loop).result(timeout=5)
        if self._thread.is_alive():
            self._thread.join(timeout=5)
        if self._modem is not None:
            self._modem.stop()
            self._modem = None

    # -- the server thread -----------------------------------------------------
    def _run(self) -> None:
        try:
            asyncio.run(self._serve())
        except BaseException as err:  # report start failures to start()
            if not self._ready.done():
                self._ready.set_exception(err)
            else:
                log.exception("%s: Modbus server stopped with an error", self.name)

    async def _serve(self) -> None:
        self._loop = asyncio.get_running_loop()
        if self.transport == "tcp":
            server: ModbusTcpServer | ModbusSerialServer = ModbusTcpServer(
                self._device, address=(self.host, self.port), trace_packet=self._trace
            )
        else:
            assert self._modem is not None
            server = ModbusSerialServer(
                self._device,
                framer=FramerType.RTU,
                port=self._modem.port_a,
                baudrate=self.baudrate,
                trace_packet=self._trace,
            )
        await server.serve_forever(background=True)
        if not server.is_active():
            raise OSError(f"{self.name}: the Modbus {self.transport} server did not start")
        if self.transport == "tcp":
            self.port = server.transport.sockets[0].getsockname()[1]  # type: ignore[attr-defined]
        self._server = server
        self._ready.set_result(None)
        await server.serving
        # Let the transports' close callbacks run before the loop goes away.
        for _ in range(3):
            await asyncio.sleep(0)

    def _trace(self, sending: bool, packet: bytes) -> bytes:
        if not sending or not packet:
            return packet
        decision = self.faults.decide()
        held, self._held = self._held, b""
        if decision == "drop":
            log.info("%s: fault: reply dropped", self.name)
            return held
        if decision == "garble":
            log.info("%s: fault: reply garbled", self.name)
            return held + _garble(packet, self.transport)
        if decision == "late":
            log.info("%s: fault: reply held back until the next", self.name)
            self._held = packet
            return held
        return held + packet


def _garble(packet: bytes, transport: str) -> bytes:
    """Corrupt a reply the way a noisy line or a broken gateway would."""
    damaged = bytearray(packet)
    if transport == "rtu":
        damaged[-1] ^= 0xA5  # the CRC no longer matches
    else:
        damaged[0] ^= 0x5A  # MBAP transaction id no longer matches the request
    return bytes(damaged)
