"""The simulated UR controller on the wire: dashboard lines, state packets, URScript."""

import contextlib
import socket
import struct
import time

import numpy as np
import pytest

from drivers.ur._realtime import StateStream
from rig.clock import RealClock, VirtualClock
from rig.config import Axis, default_rig_config
from rig.errors import ConfigError
from rig.ur_kinematics import Pose, forward
from sim.peers.ur import ScriptError, UrControllerPeer, parse_program
from sim.world import World

pytestmark = pytest.mark.timeout(30)

PACKET_SIZE = 1116
# byte offsets in the published real-time layout (after the int32 size and the time)
Q_TARGET, Q_ACTUAL = 12, 12 + 5 * 48
ROBOT_MODE = 4 + 8 + 14 * 48 + 8 + 48 + 8 + 8
SAFETY_MODE = ROBOT_MODE + 8 + 48
PROGRAM_STATE = 4 + 8 + 14 * 48 + 8 + 48 + 8 + 8 + 8 + 48 + 8 + 48 + 24 + 48 + 7 * 8 + 48 + 8


@pytest.fixture
def peer():
    controller = UrControllerPeer(World(default_rig_config(), RealClock())).start()
    yield controller
    controller.stop()


def _dashboard(peer, *commands):
    with socket.create_connection(("127.0.0.1", peer.dashboard_port), timeout=2) as sock:
        stream = sock.makefile("rwb")
        replies = [stream.readline().decode().strip()]
        for command in commands:
            stream.write(command.encode() + b"\n")
            stream.flush()
            replies.append(stream.readline().decode().strip())
        stream.close()
    return replies


def _packet(sock) -> bytes:
    data = b""
    while len(data) < PACKET_SIZE:
        data += sock.recv(PACKET_SIZE - len(data))
    return data


def _doubles(packet: bytes, offset: int, count: int) -> np.ndarray:
    return np.array(struct.unpack_from(f">{count}d", packet, offset))


def test_dashboard_greets_and_answers_each_line(peer):
    replies = _dashboard(peer, "robotmode", "safetystatus", "programState", "power on", "fly")
    assert replies == [
        "Connected: Universal Robots Dashboard Server",
        "Robotmode: POWER_OFF",
        "Safetystatus: NORMAL",
        "STOPPED <unnamed>",
        "Powering on",
        "could not understand: 'fly'",
    ]


def test_state_packets_follow_the_published_layout(peer):
    with socket.create_connection(("127.0.0.1", peer.realtime_port), timeout=2) as sock:
        packet = _packet(sock)
    assert struct.unpack_from(">i", packet)[0] == PACKET_SIZE
    q = _doubles(packet, Q_ACTUAL, 6)
    assert np.degrees(q) == pytest.approx([0, -90, 90, -90, -90, 0])
    assert np.degrees(_doubles(packet, Q_TARGET, 6)) == pytest.approx(np.degrees(q))
    assert _doubles(packet, ROBOT_MODE, 1)[0] == 3  # POWER_OFF
    assert _doubles(packet, SAFETY_MODE, 1)[0] == 1  # NORMAL
    assert _doubles(packet, PROGRAM_STATE, 1)[0] == 1  # stopped
    tool = _doubles(packet, 4 + 8 + 9 * 48, 6)  # tool vector actual
    assert Pose(tuple(tool[:3]), tuple(tool[3:])).matrix() == pytest.approx(forward(q), abs=1e-9)


def test_stream_runs_at_the_controller_rate(peer):
    """500 Hz, the e-Series rate (a loaded machine may stretch the cycle, never shorten it)."""
    with socket.create_connection(("127.0.0.1", peer.realtime_port), timeout=2) as sock:
        first = _doubles(_packet(sock), 4, 1)[0]
        for _ in range(100):
            last = _doubles(_packet(sock), 4, 1)[0]
    assert 100 / 500 * 0.8 < last - first < 100 / 500 * 3


def test_packets_go_out_as_they_are_made(peer):
    """Neither end holds a small write back for the other's ACK (Nagle's algorithm): with
    it, a reader waiting for the next state packet waited up to the kernel's delayed
    ACK (40 ms) instead of one cycle (2 ms)."""
    stream = StateStream("127.0.0.1", peer.realtime_port, timeout_s=2.0, device="arm")
    with contextlib.closing(stream):
        stream.latest()
        (client,) = [c for c in peer._server._clients if c.role == "realtime"]
        ends = (client.sock, stream._sock)
        assert [s.getsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY) for s in ends] == [1, 1]


def _run(peer, script: str, wait_s: float = 2.0) -> None:
    _dashboard(peer, "power on")
    time.sleep(0.25)
    _dashboard(peer, "brake release")
    time.sleep(0.25)
    with socket.create_connection(("127.0.0.1", peer.realtime_port), timeout=2) as sock:
        sock.sendall(script.encode())
        deadline = time.monotonic() + wait_s
        while time.monotonic() < deadline and _doubles(_packet(sock), PROGRAM_STATE, 1)[0] != 2:
            pass
        while time.monotonic() < deadline and _doubles(_packet(sock), PROGRAM_STATE, 1)[0] == 2:
            pass


def test_movel_to_a_pose_moves_the_joints_there(peer):
    start = peer.tool_pose()
    x, y, z = start.position_m
    target = Pose((x + 0.03, y, z - 0.03), start.rotvec)
    _run(peer, f"def go():\n  movel({target.script()}, a=3.0, v=2.0)\nend\n")
    assert peer.tool_pose().matrix() == pytest.approx(target.matrix(), abs=1e-5)
    assert peer.errors == []


def test_an_unreachable_pose_is_refused_in_the_log_and_nothing_moves(peer):
    joints = peer.joints_deg()
    _run(peer, "movej(p[1.5, 0, 0.2, 0, 3.1416, 0], a=1.0, v=1.0)\n", wait_s=0.3)
    assert peer.joints_deg() == pytest.approx(joints)
    assert len(peer.errors) == 1 and "out of reach" in peer.errors[0]


def test_unknown_fault_keys_are_named():
    world = World(default_rig_config(), RealClock())
    with pytest.raises(ConfigError, match=r"unknown fault\(s\) \['collision'\]"):
        UrControllerPeer(world, faults={"collision": True})


def test_parse_a_program_block_with_defaults():
    program = parse_program(
        "def btfrig_move():\n"
        "  set_tcp(p[0, 0, 0.1, 0, 0, 0])\n"
        "  movej([0, -1.57, 1.57, 0, 0, 0])\n"
        "end\n"
    )
    assert program.name == "btfrig_move"
    tcp, move = program.statements
    assert (tcp.name, tcp.is_pose, tcp.vector[2]) == ("set_tcp", True, 0.1)
    assert (move.name, move.is_pose, move.keyword("a"), move.keyword("v")) == (
        "movej",
        False,
        1.4,
        1.05,
    )


@pytest.mark.parametrize(
    ("script", "message"),
    [
        ("", "empty program"),
        ("def go():\n  movej([0,0,0,0,0,0])\n", "no 'end'"),
        ("speedj([0,0,0,0,0,0], 1.0)", "unknown function 'speedj'"),
        ("movej([0,0,0,0,0])", "six values"),
        ("movel([0,0,0,0,0,0])", r"p\[…\]"),
        ("movej([0,0,0,0,0,0], r=0.1)", "unknown argument 'r=0.1'"),
        ("movej([0,0,0,0,0,0], a=-1)", "must be > 0"),
        ("movej([0,0,zero,0,0,0])", "'zero' is not a number"),
        ("movej [0,0,0,0,0,0]", "syntax error"),
    ],
)
def test_bad_programs_are_refused_saying_why(script, message):
    with pytest.raises(ScriptError, match=message):
        parse_program(script)


def test_movej_is_a_straight_line_in_joint_space():
    clock = VirtualClock()
    peer = UrControllerPeer(World(default_rig_config(), clock), faults={"powered": True})
    try:
        start = peer.joints_deg()
        goal = start + np.array([40.0, -10.0, 20.0, 0.0, 5.0, -80.0])
        peer.state.run_script(
            f"movej([{', '.join(str(q) for q in np.radians(goal))}], a=1.0, v=0.5)"
        )
        lead = Axis(
            speed_deg_s=np.degrees(0.5), accel_deg_s2=np.degrees(1.0), min_deg=0, max_deg=720
        )
        duration = float(lead.move_time_s(80.0))  # the joint going furthest sets the time
        for t in (0.2, 0.5, 0.8):
            clock.advance_to(t * duration)
            progress = (peer.joints_deg() - start) / (goal - start + (goal == start))
            moving = goal != start
            assert np.ptp(progress[moving]) < 1e-9 and 0 < progress[moving][0] < 1
        clock.advance_to(duration - 1e-3)
        assert peer.state.snapshot()["program_state"] == 2.0
        clock.advance_to(duration)
        assert peer.joints_deg() == pytest.approx(goal, abs=1e-9)
        assert peer.state.snapshot()["program_state"] == 1.0
    finally:
        peer.stop()
