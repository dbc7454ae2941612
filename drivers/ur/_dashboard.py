"""The controller's dashboard server (port 29999): one text line out, one line back.

On connecting the server greets (``Connected: Universal Robots Dashboard
Server``); each command is a line ending in ``\\n`` and gets one reply line.
The driver uses ``power on``, ``brake release``, ``unlock protective stop``,
``close safety popup``, ``robotmode``, ``safetystatus`` and ``programState``.
"""

from __future__ import annotations

import socket

from drivers.errors import DeviceError, DeviceTimeout, ProtocolError

__all__ = ["Dashboard"]

_GREETING = "Connected: Universal Robots Dashboard Server"
_MAX_LINE = 4096


class Dashboard:
    """A connection to the dashboard server; ``request`` sends a command and returns the reply."""

    def __init__(self, host: str, port: int, *, timeout_s: float, device: str):
        self.device = device
        self._timeout_s = timeout_s
        self._buffer = b""
        try:
            self._sock = socket.create_connection((host, port), timeout=timeout_s)
        except OSError as err:
            raise DeviceTimeout(
                device, "connect", f"no dashboard server at {host}:{port}: {err}"
            ) from err
        try:
            greeting = self._read_line("connect")
        except DeviceError:
            self._sock.close()
            raise
        if not greeting.startswith(_GREETING):
            self._sock.close()
            raise ProtocolError(
                device, "connect", f"{host}:{port} greeted {greeting!r}, not a UR dashboard server"
            )

    def request(self, command: str) -> str:
        """Send ``command`` and return the reply line (stripped)."""
        try:
            self._sock.sendall(command.encode("ascii") + b"\n")
        except OSError as err:
            raise DeviceTimeout(self.device, command, f"connection lost: {err}") from err
        return self._read_line(command)

    def close(self) -> None:
        """Close the connection; idempotent."""
        self._sock.close()

    def _read_line(self, operation: str) -> str:
        while b"\n" not in self._buffer:
            try:
                chunk = self._sock.recv(_MAX_LINE)
            except TimeoutError as err:
                raise DeviceTimeout(
                    self.device, operation, f"no dashboard reply within {self._timeout_s} s"
                ) from err
            except OSError as err:
                raise DeviceTimeout(self.device, operation, f"connection lost: {err}") from err
            if not chunk:
                raise DeviceTimeout(
                    self.device, operation, "the dashboard server closed the connection"
                )
            self._buffer += chunk
            if len(self._buffer) > _MAX_LINE:
                raise ProtocolError(
                    self.device, operation, f"a reply line longer than {_MAX_LINE} bytes"
                )
        line, _, self._buffer = self._buffer.partition(b"\n")
        return line.decode("utf-8", errors="replace").strip()
