"""The fake NXT brick on its own: telegrams in, replies out (written against the
spec's byte layouts, not the driver), found by pyusb, and framed on a pty."""

import struct

import pytest
import serial
import usb.core
import usb.util

from rig.clock import VirtualClock
from rig.config import RigConfig
from sim.peers.nxt import FakeNxtBrick, FakeNxtUsbBackend, NxtSerialPeer
from sim.world import World


@pytest.fixture
def world():
    return World(RigConfig(), VirtualClock())


@pytest.fixture
def brick(world):
    return FakeNxtBrick(world)


def _output_state(reply: bytes) -> dict:
    fields = struct.unpack("<BBBBbBBbBIiii", reply)
    names = [
        "type",
        "opcode",
        "status",
        "port",
        "power",
        "mode",
        "regulation",
        "turn",
        "run",
        "limit",
        "tacho",
        "block",
        "rotation",
    ]
    return dict(zip(names, fields, strict=True))


def test_battery_level_reply(brick):
    brick.faults.battery_mv = 7421
    assert brick.handle(bytes([0x00, 0x0B])) == bytes([0x02, 0x0B, 0x00]) + struct.pack("<H", 7421)


def test_tacho_limited_move_takes_world_time_and_counts_degrees(brick, world):
    # port A, +50 %, on|brake|regulated, speed regulation, RUNNING, 240 motor degrees
    assert brick.handle(bytes.fromhex("00 04 00 32 07 01 00 20 f0 00 00 00")) == bytes.fromhex(
        "02 04 00"
    )
    state = _output_state(brick.handle(bytes.fromhex("00 06 00")))
    assert (state["status"], state["run"], state["limit"], state["power"]) == (0, 0x20, 240, 50)
    assert state["rotation"] == 0
    tilt = 240 * world.config.laser.device.gear_ratio  # 10° of sheet tilt
    world.clock.sleep(tilt / world.config.laser.sweep_speed_deg_s / 2)  # half way in time
    mid = _output_state(brick.handle(bytes.fromhex("00 06 00")))
    assert 60 < mid["rotation"] < 180
    assert mid["run"] == 0x20
    world.clock.sleep(tilt / world.config.laser.sweep_speed_deg_s)
    done = _output_state(brick.handle(bytes.fromhex("00 06 00")))
    assert (done["rotation"], done["tacho"], done["block"], done["run"]) == (240, 240, 240, 0x00)
    assert world.position("laser_tilt") == pytest.approx(tilt)


def test_reset_motor_position_zeroes_the_right_counter(brick, world):
    brick.handle(bytes.fromhex("00 04 00 32 07 01 00 20 30 00 00 00"))  # 48°
    world.clock.sleep(60)
    assert brick.handle(bytes.fromhex("00 0a 00 01")) == bytes.fromhex("02 0a 00")  # block
    state = _output_state(brick.handle(bytes.fromhex("00 06 00")))
    assert (state["tacho"], state["block"], state["rotation"]) == (48, 0, 48)
    brick.handle(bytes.fromhex("00 0a 00 00"))  # rotation
    state = _output_state(brick.handle(bytes.fromhex("00 06 00")))
    assert (state["tacho"], state["block"], state["rotation"]) == (48, 0, 0)


def test_laser_port_switches_the_world_laser(brick, world):
    brick.handle(bytes.fromhex("00 04 01 64 01 00 00 20 00 00 00 00"))
    assert world.snapshot().laser_on
    brick.handle(bytes.fromhex("00 04 01 00 00 00 00 00 00 00 00 00"))
    assert not world.snapshot().laser_on


def test_no_reply_type_executes_silently(brick, world):
    assert brick.handle(bytes.fromhex("80 04 01 64 01 00 00 20 00 00 00 00")) is None
    assert world.snapshot().laser_on


@pytest.mark.parametrize(
    ("telegram", "reply"),
    [
        ("00 03 00", "02 03 be"),  # PLAYTONE is not implemented: unknown opcode
        ("00 06", "02 06 bf"),  # GETOUTPUTSTATE without its port byte: insane packet
        ("00 06 05", "02 06 f0"),  # no output port 5
        ("00 04 00 7f 07 01 00 20 00 00 00 00", "02 04 c0"),  # power 127
        ("00 0a 00 02", "02 0a c0"),  # relative flag must be 0 or 1
    ],
)
def test_errors_get_the_spec_status(brick, telegram, reply):
    assert brick.handle(bytes.fromhex(telegram)) == bytes.fromhex(reply)


def test_faults_lost_garbled_deaf(brick):
    brick.faults.lost_replies = 1
    assert brick.handle(bytes([0x00, 0x0B])) is None
    brick.faults.garbled_replies = 1
    garbled = brick.handle(bytes([0x00, 0x0B]))
    assert garbled[0] != 0x02 and garbled[1:3] == bytes([0x0B, 0x00])
    assert brick.handle(bytes([0x00, 0x0B]))[0] == 0x02
    brick.faults.deaf = True
    assert brick.handle(bytes([0x00, 0x0B])) is None


def test_pyusb_finds_the_fake_brick_and_talks_bulk(brick):
    backend = FakeNxtUsbBackend(brick)
    dev = usb.core.find(idVendor=0x0694, idProduct=0x0002, backend=backend)
    assert dev is not None
    assert usb.core.find(idVendor=0x0694, idProduct=0x0003, backend=backend) is None
    try:
        dev.set_configuration()
        interface = dev.get_active_configuration()[(0, 0)]
        addresses = sorted(ep.bEndpointAddress for ep in interface)
        assert addresses == [0x01, 0x82]
        assert dev.write(0x01, bytes([0x00, 0x0B]), timeout=100) == 2
        assert bytes(dev.read(0x82, 64, timeout=100))[:3] == bytes([0x02, 0x0B, 0x00])
        with pytest.raises(usb.core.USBTimeoutError):
            dev.read(0x82, 64, timeout=10)
        assert backend.open_handles == 1
    finally:
        usb.util.dispose_resources(dev)
    assert backend.open_handles == 0


def test_serial_peer_frames_with_a_length_prefix_and_resyncs(brick):
    brick.faults.battery_mv = 8100
    with NxtSerialPeer(brick) as peer, serial.Serial(peer.port, timeout=0.5) as port:
        port.write(bytes.fromhex("02 00 00 0b"))
        assert port.read(7) == bytes.fromhex("05 00 02 0b 00") + struct.pack("<H", 8100)
        port.write(bytes.fromhex("ff ff 00 0b"))  # impossible length: dropped
        port.timeout = 0.1
        assert port.read(1) == b""
        port.write(bytes.fromhex("02 00 00 0b"))  # back-to-back telegrams
        port.write(bytes.fromhex("03 00 00 06 00"))
        port.timeout = 0.5
        assert port.read(7)[2:4] == bytes([0x02, 0x0B])
        assert port.read(27)[:5] == bytes.fromhex("19 00 02 06 00")
