"""The Dynamixel bus emulator on its pty, spoken to in raw bytes (no SDK, no driver)."""

import time

import pytest
import serial

from rig.clock import VirtualClock
from rig.config import default_rig_config
from rig.errors import ConfigError
from sim.peers import DynamixelBusPeer
from sim.peers.dynamixel import PacketReader, encode
from sim.world import World

SERVOS = default_rig_config().light_arc.device.model_copy(update={"ids": (1, 2)})


def h(text: str) -> bytes:
    return bytes.fromhex(text)


@pytest.fixture
def world():
    return World(default_rig_config(), VirtualClock())


@pytest.fixture
def bus(world):
    peer = DynamixelBusPeer(world, servos=SERVOS).start()
    yield peer
    peer.stop()


@pytest.fixture
def line(bus):
    port = serial.Serial(bus.serial_port, 57600, timeout=0.2)
    yield port
    port.close()


def exchange(line, request: bytes, replies: int = 1, wait_s: float = 0.3):
    """Send ``request``; return the status packets read within ``wait_s``."""
    line.write(request)
    reader, packets = PacketReader(), []
    deadline = time.monotonic() + wait_s
    while len(packets) < replies and time.monotonic() < deadline:
        packets.extend(reader.feed(line.read(64)))
    return packets


def test_ping_answers_model_and_firmware(line):
    line.write(h("FF FF FD 00 01 03 00 01 19 4E"))  # the e-manual's PING of id 1
    expected = encode(1, 0x55, h("00 FC 03 2E"))  # error 0, model 1020, firmware 46
    got = b""
    deadline = time.monotonic() + 0.5
    while len(got) < len(expected) and time.monotonic() < deadline:
        got += line.read(len(expected) - len(got))
    assert got == expected


def test_broadcast_ping_answers_every_servo(line):
    packets = exchange(line, encode(0xFE, 0x01), replies=2)
    assert [p.servo_id for p in packets] == [1, 2]


def test_unknown_id_is_silent(line):
    assert exchange(line, encode(7, 0x01), wait_s=0.2) == []


def test_write_goal_moves_the_world_arc(line, world):
    (torque,) = exchange(line, encode(1, 0x03, h("40 00 01")))  # torque enable = 1
    assert torque.params == b"\x00"
    goal = 1024  # 90° at 4096 ticks per arc turn
    (status,) = exchange(line, encode(1, 0x03, h("74 00") + goal.to_bytes(4, "little")))
    assert status.params == b"\x00"
    assert world.arc.target_deg == pytest.approx(90.0)
    world.clock.sleep(20.0)
    (present,) = exchange(line, encode(1, 0x02, h("84 00 04 00")))
    assert present.params == b"\x00" + goal.to_bytes(4, "little")


def test_goal_without_torque_does_not_move(line, world):
    exchange(line, encode(1, 0x03, h("74 00") + (512).to_bytes(4, "little")))
    assert world.arc.target_deg == 0.0


def test_sync_write_then_sync_read(line, world):
    exchange(line, encode(0xFE, 0x03, h("40 00 01")), replies=0, wait_s=0.05)  # broadcast write
    params = h("74 00 04 00") + b"\x01" + (200).to_bytes(4, "little")
    params += b"\x02" + (200).to_bytes(4, "little")
    assert exchange(line, encode(0xFE, 0x83, params), replies=1, wait_s=0.1) == []  # no reply
    packets = exchange(line, encode(0xFE, 0x82, h("74 00 04 00 02 01")), replies=2)
    assert [(p.servo_id, p.params) for p in packets] == [
        (2, b"\x00" + (200).to_bytes(4, "little")),
        (1, b"\x00" + (200).to_bytes(4, "little")),
    ]


@pytest.mark.parametrize(
    ("request_hex", "error"),
    [
        ("02 93 00 04 00", 4),  # READ 147 + 4: beyond the table → data range
        ("03 84 00 00 00 00 00", 7),  # WRITE present position → access error
        ("02 84 00", 5),  # READ with a missing length byte → data length
        ("55", 2),  # a status packet sent as instruction → instruction error
    ],
)
def test_errors_in_the_status_packet(line, request_hex, error):
    body = h(request_hex)
    (status,) = exchange(line, encode(1, body[0], body[1:]))
    assert status.params[0] == error


def test_eeprom_is_locked_while_torque_is_on(line):
    assert exchange(line, encode(1, 0x03, h("0B 00 03")))[0].params == b"\x00"  # mode 3: ok
    exchange(line, encode(1, 0x03, h("40 00 01")))
    assert exchange(line, encode(1, 0x03, h("0B 00 04")))[0].params == b"\x07"


def test_a_damaged_instruction_gets_a_crc_error(line):
    bad = bytearray(encode(1, 0x02, h("84 00 04 00")))
    bad[-2] ^= 0x01
    (status,) = exchange(line, bytes(bad))
    assert status.params == b"\x03"


def test_hardware_error_sets_the_alert_and_reboot_clears_it(line, bus):
    bus.set_hardware_error(2, 0x20)
    (status,) = exchange(line, encode(2, 0x02, h("46 00 01 00")))
    assert status.params == b"\x80\x20"  # alert bit, then the hardware error status
    exchange(line, encode(2, 0x08))
    (status,) = exchange(line, encode(2, 0x02, h("46 00 01 00")))
    assert status.params == b"\x00\x00"


def test_reply_faults(line, bus):
    bus.faults.drop_next(1)
    assert exchange(line, encode(1, 0x01), wait_s=0.2) == []
    bus.faults.garble_next(1)
    (packet,) = exchange(line, encode(1, 0x01))
    assert not packet.crc_ok
    assert exchange(line, encode(1, 0x01))[0].crc_ok
    bus.faults.late_next(1)
    assert exchange(line, encode(1, 0x01), wait_s=0.2) == []
    late, answer = exchange(line, encode(2, 0x01), replies=2)  # the held one comes first
    assert (late.servo_id, answer.servo_id) == (1, 2)


def test_fault_table(world):
    peer = DynamixelBusPeer(
        world, servos=SERVOS, faults={"hardware_error": {2: 0x04}, "stall_fraction": 0.25}
    )
    assert peer.servos[2].hardware_error == 0x04
    assert world.arc.stall_fraction == 0.25
    with pytest.raises(ConfigError, match=r"unknown fault\(s\) \['smoke'\]; valid are"):
        DynamixelBusPeer(world, faults={"smoke": True})
    with pytest.raises(ConfigError, match="no servo 9 on the bus"):
        DynamixelBusPeer(world, servos=SERVOS, faults={"hardware_error": {9: 1}})


def test_stop_is_idempotent_and_closes_the_pty(world):
    peer = DynamixelBusPeer(world).start()
    path = peer.serial_port
    peer.stop()
    peer.stop()
    with pytest.raises(RuntimeError, match="not started"):
        _ = peer.serial_port
    assert path.startswith("/dev/pts/")
