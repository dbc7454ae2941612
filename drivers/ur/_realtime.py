"""The controller's real-time interface (port 30003): URScript in, robot state out.

The controller streams one packet per control cycle (125 Hz on CB3, 500 Hz on
e-Series) to every client; a client may send URScript on the same socket. The
packet layout is the one of CB3 3.10–3.15 and e-Series 5.4–5.8 (Universal
Robots, "Client interfaces", real-time tab): a big-endian int32 message size
(1116, itself included) followed by big-endian doubles. ``STATE_FIELDS`` lists
them in order with their counts; ``RobotState`` keeps the ones the driver
reads.
"""

from __future__ import annotations

import enum
import itertools
import select
import socket
import struct
from dataclasses import dataclass

import numpy as np

from drivers.errors import DeviceTimeout, ProtocolError

__all__ = ["PACKET_SIZE", "STATE_FIELDS", "RobotMode", "RobotState", "SafetyMode", "StateStream"]

# (name, number of doubles), in stream order after the int32 message size.
STATE_FIELDS: tuple[tuple[str, int], ...] = (
    ("time", 1),
    ("q_target", 6),
    ("qd_target", 6),
    ("qdd_target", 6),
    ("i_target", 6),
    ("m_target", 6),
    ("q_actual", 6),
    ("qd_actual", 6),
    ("i_actual", 6),
    ("i_control", 6),
    ("tool_vector_actual", 6),
    ("tcp_speed_actual", 6),
    ("tcp_force", 6),
    ("tool_vector_target", 6),
    ("tcp_speed_target", 6),
    ("digital_input_bits", 1),
    ("motor_temperatures", 6),
    ("controller_timer", 1),
    ("test_value", 1),
    ("robot_mode", 1),
    ("joint_modes", 6),
    ("safety_mode", 1),
    ("unused_1", 6),
    ("tool_accelerometer", 3),
    ("unused_2", 6),
    ("speed_scaling", 1),
    ("linear_momentum_norm", 1),
    ("software_only", 1),
    ("software_only_2", 1),
    ("v_main", 1),
    ("v_robot", 1),
    ("i_robot", 1),
    ("v_actual", 6),
    ("digital_outputs", 1),
    ("program_state", 1),
    ("elbow_position", 3),
    ("elbow_velocity", 3),
    ("safety_status", 1),
)
_DOUBLES = struct.Struct(">" + "d" * sum(count for _, count in STATE_FIELDS))
_SIZE = struct.Struct(">i")
PACKET_SIZE = _SIZE.size + _DOUBLES.size  # 1116
_COUNTS = [count for _, count in STATE_FIELDS]
# field → (index of its first double, number of doubles)
_OFFSETS = {
    name: (start, count)
    for (name, count), start in zip(
        STATE_FIELDS, itertools.accumulate(_COUNTS, initial=0), strict=False
    )
}


class RobotMode(enum.IntEnum):
    """``robot_mode`` of the stream (and, by name, the dashboard's ``robotmode``)."""

    NO_CONTROLLER = -1
    DISCONNECTED = 0
    CONFIRM_SAFETY = 1
    BOOTING = 2
    POWER_OFF = 3
    POWER_ON = 4
    IDLE = 5
    BACKDRIVE = 6
    RUNNING = 7
    UPDATING_FIRMWARE = 8


class SafetyMode(enum.IntEnum):
    """``safety_mode`` of the stream (and, by name, the dashboard's ``safetystatus``)."""

    NORMAL = 1
    REDUCED = 2
    PROTECTIVE_STOP = 3
    RECOVERY = 4
    SAFEGUARD_STOP = 5
    SYSTEM_EMERGENCY_STOP = 6
    ROBOT_EMERGENCY_STOP = 7
    VIOLATION = 8
    FAULT = 9
    VALIDATE_JOINT_ID = 10
    UNDEFINED_SAFETY_MODE = 11
    AUTOMATIC_MODE_SAFEGUARD_STOP = 12
    SYSTEM_THREE_POSITION_ENABLING_STOP = 13


PROGRAM_RUNNING = 2.0  # ``program_state`` while a program (a sent script) runs; 1: stopped


@dataclass(frozen=True)
class RobotState:
    """One packet of the stream, the fields the driver reads (radians, metres)."""

    time_s: float
    q_target: np.ndarray
    q_actual: np.ndarray
    robot_mode: RobotMode
    safety_mode: SafetyMode
    program_running: bool

    @classmethod
    def decode(cls, packet: bytes, *, device: str) -> RobotState:
        """Decode one whole packet (``PACKET_SIZE`` bytes, size prefix included)."""
        (size,) = _SIZE.unpack_from(packet)
        if size != PACKET_SIZE or len(packet) != PACKET_SIZE:
            raise ProtocolError(
                device,
                "read state",
                f"a state packet of {size} bytes (got {len(packet)}); this driver reads the "
                f"{PACKET_SIZE}-byte layout of CB3 3.10+ / e-Series 5.4–5.8 controllers",
            )
        values = np.array(_DOUBLES.unpack_from(packet, _SIZE.size))

        def field(name: str) -> np.ndarray:
            at, count = _OFFSETS[name]
            return values[at : at + count]

        try:
            robot_mode = RobotMode(int(field("robot_mode")[0]))
            safety_mode = SafetyMode(int(field("safety_mode")[0]))
        except ValueError as err:
            raise ProtocolError(
                device, "read state", f"unknown mode in a state packet: {err}"
            ) from err
        return cls(
            time_s=float(field("time")[0]),
            q_target=field("q_target").copy(),
            q_actual=field("q_actual").copy(),
            robot_mode=robot_mode,
            safety_mode=safety_mode,
            program_running=field("program_state")[0] == PROGRAM_RUNNING,
        )


class StateStream:
    """A connection to the real-time port: send URScript, read the latest state.

    The controller keeps sending whether or not anyone reads; ``latest``
    drains what has queued and returns the newest whole packet that arrived
    after the call began, so a state is never older than one cycle.
    """

    def __init__(self, host: str, port: int, *, timeout_s: float, device: str):
        self.device = device
        self._timeout_s = timeout_s
        self._buffer = bytearray()
        try:
            self._sock = socket.create_connection((host, port), timeout=timeout_s)
            # a script goes out at once, not held back for the ACK of the last one
            self._sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        except OSError as err:
            raise DeviceTimeout(
                device, "connect", f"no real-time interface at {host}:{port}: {err}"
            ) from err

    def send_script(self, script: str) -> None:
        """Send a URScript program (ends with a newline)."""
        try:
            self._sock.sendall(script.encode("utf-8"))
        except OSError as err:
            raise DeviceTimeout(self.device, "send script", f"connection lost: {err}") from err

    def latest(self) -> RobotState:
        """The newest state; raises ``DeviceTimeout`` when the stream stops or the link drops."""
        while select.select([self._sock], [], [], 0)[0]:
            self._buffer += self._recv(65536)
        # Whole packets queued before this call are stale; a partial one is the newest.
        del self._buffer[: len(self._buffer) - len(self._buffer) % PACKET_SIZE]
        while len(self._buffer) < PACKET_SIZE:
            self._buffer += self._recv(PACKET_SIZE - len(self._buffer))
        packet = bytes(self._buffer[:PACKET_SIZE])
        del self._buffer[:PACKET_SIZE]
        return RobotState.decode(packet, device=self.device)

    def close(self) -> None:
        """Close the connection; idempotent."""
        self._sock.close()

    def _recv(self, count: int) -> bytes:
        try:
            chunk = self._sock.recv(count)
        except TimeoutError as err:
            raise DeviceTimeout(
                self.device, "read state", f"no state packet within {self._timeout_s} s"
            ) from err
        except OSError as err:
            raise DeviceTimeout(self.device, "read state", f"connection lost: {err}") from err
        if not chunk:
            raise DeviceTimeout(self.device, "read state", "the controller closed the connection")
        return chunk
