"""The simulated controller's two TCP servers, served by one thread.

- Dashboard (29999 on a controller): greets, then answers one line per command.
- Real-time interface (30003): streams a 1116-byte state packet (CB3 3.10+ /
  e-Series 5.4–5.8 layout, big-endian) to every client at ``rate_hz`` and
  runs every URScript program a client sends (one line, or a ``def … end``
  block).

A client that does not keep up misses packets (whole ones), as on a
controller. ``drop_connections`` closes every client socket (a cable pulled);
the servers keep listening.
"""

from __future__ import annotations

import logging
import selectors
import socket
import struct
import threading
import time

import numpy as np

from sim.peers.ur._controller import ControllerState

__all__ = ["ControllerServer"]

log = logging.getLogger(__name__)

# The real-time packet after its int32 size: (field, number of doubles), from the
# controller's published client-interface table; unnamed fields are sent as 0.
_LAYOUT = (
    ("time", 1), ("q_target", 6), ("qd_target", 6), ("qdd_target", 6), ("i_target", 6),
    ("m_target", 6), ("q_actual", 6), ("qd_actual", 6), ("i_actual", 6), ("i_control", 6),
    ("tool_vector_actual", 6), ("tcp_speed_actual", 6), ("tcp_force", 6),
    ("tool_vector_target", 6), ("tcp_speed_target", 6), ("digital_input_bits", 1),
    ("motor_temperatures", 6), ("controller_timer", 1), ("test_value", 1), ("robot_mode", 1),
    ("joint_modes", 6), ("safety_mode", 1), ("reserved_1", 6), ("tool_accelerometer", 3),
    ("reserved_2", 6), ("speed_scaling", 1), ("linear_momentum_norm", 1), ("reserved_3", 1),
    ("reserved_4", 1), ("v_main", 1), ("v_robot", 1), ("i_robot", 1), ("v_actual", 6),
    ("digital_outputs", 1), ("program_state", 1), ("elbow_position", 3), ("elbow_velocity", 3),
    ("safety_status", 1),
)  # fmt: skip
_COUNT = sum(n for _, n in _LAYOUT)
_PACKET = struct.Struct(f">i{_COUNT}d")
_GREETING = b"Connected: Universal Robots Dashboard Server\n"


def encode_state(fields: dict) -> bytes:
    """A state packet with ``fields`` (name → value or sequence) set, the rest 0."""
    values = []
    for name, count in _LAYOUT:
        value = np.ravel(fields.get(name, np.zeros(count)))
        values.extend(float(v) for v in value)
    return _PACKET.pack(_PACKET.size, *values)


class _Client:
    def __init__(self, sock: socket.socket, role: str):
        self.sock = sock
        self.role = role
        self.inbox = b""
        self.outbox = b""


class ControllerServer:
    """Dashboard + real-time servers on loopback ports for one ``ControllerState``."""

    def __init__(
        self,
        state: ControllerState,
        *,
        host: str = "127.0.0.1",
        dashboard_port: int = 0,
        realtime_port: int = 0,
        rate_hz: float = 500.0,
    ):
        self.state = state
        self.host = host
        self._period_s = 1.0 / rate_hz
        self._selector = selectors.DefaultSelector()
        self._listeners = {}
        for role, port in (("dashboard", dashboard_port), ("realtime", realtime_port)):
            listener = socket.create_server((host, port))
            listener.setblocking(False)
            self._selector.register(listener, selectors.EVENT_READ, role)
            self._listeners[role] = listener
        self._clients: list[_Client] = []
        self._drop = threading.Event()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, name="ur-controller-peer", daemon=True)

    @property
    def dashboard_port(self) -> int:
        return self._listeners["dashboard"].getsockname()[1]

    @property
    def realtime_port(self) -> int:
        return self._listeners["realtime"].getsockname()[1]

    def start(self) -> ControllerServer:
        self._thread.start()
        return self

    def drop_connections(self) -> None:
        """Close every client connection at the next cycle (the servers keep listening)."""
        self._drop.set()

    def stop(self) -> None:
        """Close every socket and end the thread; idempotent."""
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout=5)
        for client in list(self._clients):
            self._close(client)
        for listener in self._listeners.values():
            if listener.fileno() >= 0:
                self._selector.unregister(listener)
                listener.close()
        self._selector.close()

    # -- the serving thread -------------------------------------------------------
    def _serve(self) -> None:
        next_tick = 0.0  # the stream's pace is real time, whatever the simulation clock
        while not self._stop.is_set():
            for key, _ in self._selector.select(timeout=self._period_s / 4):
                if isinstance(key.data, str):
                    self._accept(key.fileobj, key.data)
                else:
                    self._receive(key.data)
            if self._drop.is_set():
                self._drop.clear()
                for client in list(self._clients):
                    self._close(client)
            now = time.monotonic()
            if now >= next_tick:
                next_tick = now + self._period_s
                self._stream()

    def _accept(self, listener: socket.socket, role: str) -> None:
        sock, _ = listener.accept()
        sock.setblocking(False)
        # a controller sends each packet as it is made: no coalescing while an ACK is awaited
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        client = _Client(sock, role)
        self._clients.append(client)
        self._selector.register(sock, selectors.EVENT_READ, client)
        if role == "dashboard":
            self._send(client, _GREETING)

    def _receive(self, client: _Client) -> None:
        try:
            chunk = client.sock.recv(65536)
        except (BlockingIOError, InterruptedError):
            return
        except OSError:
            chunk = b""
        if not chunk:
            self._close(client)
            return
        client.inbox += chunk
        if client.role == "dashboard":
            while b"\n" in client.inbox:
                line, _, client.inbox = client.inbox.partition(b"\n")
                reply = self._dashboard(line.decode("utf-8", errors="replace").strip())
                self._send(client, reply.encode() + b"\n")
        else:
            for program in self._programs(client):
                self.state.run_script(program)

    @staticmethod
    def _programs(client: _Client) -> list[str]:
        programs = []
        text = client.inbox.decode("utf-8", errors="replace")
        lines = text.split("\n")
        pending, complete = lines[:-1], lines[-1]
        block: list[str] = []
        for line in pending:
            if block or line.strip().startswith("def "):
                block.append(line)
                if line.strip() == "end":
                    programs.append("\n".join(block))
                    block = []
            elif line.strip():
                programs.append(line)
        rest = "\n".join([*block, complete]) if block else complete
        client.inbox = rest.encode("utf-8")
        return programs

    def _dashboard(self, command: str) -> str:
        state = self.state
        robot, safety, running = state.modes()
        if command == "power on":
            state.power_on()
            return "Powering on"
        if command == "power off":
            state.power_off()
            return "Powering off"
        if command == "brake release":
            state.brake_release()
            return "Brake releasing"
        if command == "unlock protective stop":
            if state.unlock_protective_stop():
                return "Protective stop releasing"
            return (
                "Cannot unlock protective stop until 5s after occurrence. "
                "Always inspect cause of protective stop before unlocking"
            )
        if command == "close safety popup":
            return "closing safety popup"
        if command == "stop":
            state.stop_program()
            return "Stopped"
        if command == "robotmode":
            return f"Robotmode: {robot}"
        if command == "safetystatus":
            return f"Safetystatus: {safety}"
        if command == "safetymode":
            return f"Safetymode: {safety}"
        if command == "programState":
            return f"{'PLAYING' if running else 'STOPPED'} {state.program_name}"
        return f"could not understand: '{command}'"

    def _stream(self) -> None:
        receivers = [c for c in self._clients if c.role == "realtime"]
        if not receivers:
            return
        packet = encode_state(self.state.snapshot())
        for client in receivers:
            if not client.outbox:  # a client still behind misses this packet, whole
                self._send(client, packet)
            else:
                self._send(client, b"")

    def _send(self, client: _Client, data: bytes) -> None:
        client.outbox += data
        try:
            sent = client.sock.send(client.outbox)
        except (BlockingIOError, InterruptedError):
            return
        except OSError:
            self._close(client)
            return
        client.outbox = client.outbox[sent:]

    def _close(self, client: _Client) -> None:
        if client in self._clients:
            self._clients.remove(client)
            self._selector.unregister(client.sock)
            client.sock.close()
