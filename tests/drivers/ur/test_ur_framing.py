"""The driver's framing: real-time state packets (bytes in, fields out), the dashboard greeting."""

import socket
import struct
import threading

import numpy as np
import pytest

from drivers.errors import ProtocolError
from drivers.ur._dashboard import Dashboard
from drivers.ur._realtime import PACKET_SIZE, RobotMode, RobotState, SafetyMode
from sim.peers.ur._server import encode_state


def test_the_layout_is_1116_bytes():
    assert PACKET_SIZE == 1116


def test_fields_come_back_from_their_places():
    q = np.radians([10.0, -80.0, 95.0, -100.0, -90.0, 30.0])
    packet = encode_state(
        {
            "time": 12.5,
            "q_target": q + 0.1,
            "q_actual": q,
            "robot_mode": 7,
            "safety_mode": 3,
            "program_state": 2.0,
        }
    )
    state = RobotState.decode(packet, device="arm")
    assert state.time_s == 12.5
    assert state.q_actual == pytest.approx(q)
    assert state.q_target == pytest.approx(q + 0.1)
    assert state.robot_mode is RobotMode.RUNNING
    assert state.safety_mode is SafetyMode.PROTECTIVE_STOP
    assert state.program_running


def test_another_controller_version_is_named():
    older = struct.pack(">i", 1108) + bytes(1104)  # CB3 3.5–3.9 layout, no safety status
    with pytest.raises(
        ProtocolError, match=r"arm: read state failed: a state packet of 1108 bytes"
    ):
        RobotState.decode(older, device="arm")


def test_an_unknown_mode_is_a_protocol_error():
    packet = encode_state({"robot_mode": 42, "safety_mode": 1})
    with pytest.raises(ProtocolError, match="unknown mode"):
        RobotState.decode(packet, device="arm")


def test_a_port_that_is_not_a_dashboard_server_is_named():
    listener = socket.create_server(("127.0.0.1", 0))

    def greet_wrongly():
        conn, _ = listener.accept()
        with conn:
            conn.sendall(b"220 FTP server ready\n")
            conn.recv(16)  # until the client hangs up

    server = threading.Thread(target=greet_wrongly)
    server.start()
    try:
        port = listener.getsockname()[1]
        with pytest.raises(ProtocolError, match=rf"arm: connect failed: 127.0.0.1:{port} greeted"):
            Dashboard("127.0.0.1", port, timeout_s=1.0, device="arm")
    finally:
        server.join(timeout=5)
        listener.close()
