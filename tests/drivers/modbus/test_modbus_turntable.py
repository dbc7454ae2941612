"""The turntable driver against the simulated stepper drive, over TCP and RTU (pty)."""

import logging

import pytest
from pymodbus.client import ModbusTcpClient

from drivers.errors import DeviceError, DeviceFault, DeviceTimeout, MotionStalled
from drivers.interfaces import Axis
from drivers.modbus import ModbusTurntable
from rig.devices import DriveRegisters, ModbusDrive, Retry
from rig.errors import KinematicsError
from sim.peers import TurntableDrivePeer


@pytest.fixture
def drive(world, transport):
    peer = TurntableDrivePeer(world, transport=transport).start()
    yield peer
    peer.stop()


@pytest.fixture
def turntable(drive, world, clock, transport, connection_to):
    config = world.config.turntable
    table = ModbusTurntable(connection_to(drive, transport), axis=config.axis, clock=clock)
    yield table
    table.close()


def test_satisfies_the_interface(turntable):
    assert isinstance(turntable, Axis)


def test_move_takes_the_profile_time_and_ends_at_the_target(turntable, world, clock):
    turntable.home()
    t0 = clock.now()
    turntable.move_to(90.0)
    assert world.is_moving("turntable")
    settled = turntable.wait_until_settled()
    elapsed = clock.now() - t0
    expected = float(world.config.turntable.axis.move_time_s(90.0))
    assert settled == pytest.approx(90.0, abs=0.01)
    assert world.position("turntable") == pytest.approx(90.0, abs=1e-9)
    # polled every 0.05 s of virtual time: arrives within one poll (and a bit of rounding)
    assert expected - 1e-6 <= elapsed <= expected + 0.05 + 1e-6


def test_position_follows_the_world_mid_move(turntable, world, clock):
    turntable.move_to(300.0)
    clock.sleep(2.0)
    assert turntable.position() == pytest.approx(world.position("turntable"), abs=0.01)
    assert 0.0 < turntable.position() < 300.0


def test_home_sets_homed(turntable, world, drive, clock):
    world.move("turntable", 45.0)
    clock.sleep(10.0)
    assert not turntable.status().homed
    turntable.home()
    assert turntable.status().homed
    assert world.position("turntable") == pytest.approx(0.0, abs=1e-9)


def test_stop_halts_where_the_axis_is(turntable, world, clock):
    turntable.move_to(300.0)
    clock.sleep(3.0)
    turntable.stop()
    where = turntable.wait_until_settled()
    assert where == pytest.approx(world.position("turntable"), abs=0.01)
    assert 10.0 < where < 300.0
    assert not world.is_moving("turntable")


def test_stall_raises_naming_axis_target_and_stop(turntable, drive, world):
    drive.set_stall(0.5)
    turntable.move_to(180.0)
    with pytest.raises(MotionStalled) as err:
        turntable.wait_until_settled()
    message = str(err.value)
    assert "turntable" in message
    assert "180.00°" in message
    assert "90.00°" in message  # half-way: where it stopped
    assert err.value.device == "turntable"


def test_drive_fault_raises_device_fault(turntable, drive):
    drive.set_drive_fault(True)
    turntable.move_to(30.0)
    with pytest.raises(DeviceFault, match=r"turntable.*fault"):
        turntable.wait_until_settled()


def test_wait_times_out_on_the_clock(turntable, clock):
    turntable.move_to(300.0)
    t0 = clock.now()
    with pytest.raises(DeviceTimeout, match="still moving"):
        turntable.wait_until_settled(timeout_s=1.0)
    assert clock.now() - t0 == pytest.approx(1.0, abs=0.051)


def test_target_outside_the_axis_is_refused_before_anything_moves(turntable, world):
    with pytest.raises(KinematicsError, match=r"400.0° is outside .*\[0.0°, 360.0°\]"):
        turntable.move_to(400.0)
    assert not world.is_moving("turntable")


def test_one_lost_reply_is_retried(turntable, drive, world, clock, caplog):
    world.move("turntable", 12.5)
    clock.sleep(10.0)
    drive.faults.drop_next(1)
    with caplog.at_level(logging.WARNING, logger="drivers.retry"):
        assert turntable.position() == pytest.approx(12.5, abs=0.01)
    assert drive.faults.dropped == 1
    assert any("retry 1/2" in r.message for r in caplog.records)


def test_one_garbled_reply_is_retried(turntable, drive, world, clock):
    world.move("turntable", 7.25)
    clock.sleep(10.0)
    drive.faults.garble_next(1)
    assert turntable.position() == pytest.approx(7.25, abs=0.01)
    assert drive.faults.garbled == 1


def test_a_silent_drive_fails_after_the_retries(turntable, drive, clock):
    drive.faults.drop_next(100)
    t0 = clock.now()
    with pytest.raises(DeviceTimeout) as err:
        turntable.position()
    assert "turntable" in str(err.value)
    assert "gave up after 3 tries" in str(err.value)
    assert drive.faults.dropped == 3
    assert clock.now() - t0 == pytest.approx(0.01 + 0.02)  # backoff doubles, virtual time
    drive.faults.clear()
    assert turntable.position() == pytest.approx(0.0)  # and the link recovers


def test_a_garbling_drive_fails_after_the_retries(turntable, drive):
    drive.faults.garble_next(100)
    with pytest.raises(DeviceError, match=r"turntable: position failed.*gave up after 3 tries"):
        turntable.position()


def test_custom_register_map_and_word_order(world, clock, transport, connection_to):
    registers = DriveRegisters(
        target_position=100,
        actual_position=110,
        status=120,
        command=121,
        speed=130,
        acceleration=131,
        units_per_deg=10.0,
        word_order="low_first",
        moving_bit=4,
        in_position_bit=5,
        fault_bit=6,
        homed_bit=7,
        go_code=0x11,
        home_code=0x22,
        stop_code=0x33,
    )
    with TurntableDrivePeer(world, registers=registers, transport=transport) as peer:
        table = ModbusTurntable(
            connection_to(peer, transport, ModbusDrive(registers=registers)),
            axis=world.config.turntable.axis,
            clock=clock,
        )
        table.move_to(123.4)
        assert table.wait_until_settled() == pytest.approx(123.4, abs=0.1)
        assert world.position("turntable") == pytest.approx(123.4)
        table.close()


def test_target_register_holds_the_documented_encoding(world, clock):
    # Ground truth from a plain Modbus client: int32, 0.01°, high word first, at 0..1.
    with TurntableDrivePeer(world) as peer:
        conn = ModbusDrive(port=peer.port, retry=Retry(timeout_s=0.2, retries=0))
        table = ModbusTurntable(conn, axis=world.config.turntable.axis, clock=clock)
        table.move_to(300.01)
        table.close()
        client = ModbusTcpClient("127.0.0.1", port=peer.port, timeout=0.2, retries=0)
        words = client.read_holding_registers(0, count=2, device_id=1).registers
        client.close()
    assert words == [30001 >> 16, 30001 & 0xFFFF]


def test_a_register_the_drive_lacks_is_a_clear_non_retried_error(world, clock):
    wrong = DriveRegisters(status=40)  # the drive has its status at 4
    with TurntableDrivePeer(world) as peer:
        conn = ModbusDrive(port=peer.port, registers=wrong, retry=Retry(timeout_s=0.2, retries=2))
        table = ModbusTurntable(conn, axis=world.config.turntable.axis, clock=clock)
        t0 = clock.now()
        with pytest.raises(DeviceError, match=r"ILLEGAL_ADDRESS.*register map") as err:
            table.status()
        table.close()
    assert type(err.value) is DeviceError
    assert clock.now() == t0  # refused, not retried


def test_unreachable_drive_is_a_timeout_naming_the_address(world, clock):
    with TurntableDrivePeer(world) as peer:
        port = peer.port
    conn = ModbusDrive(port=port, retry=Retry(timeout_s=0.2, retries=1, backoff_s=0.01))
    table = ModbusTurntable(conn, axis=world.config.turntable.axis, clock=clock)
    with pytest.raises(DeviceTimeout, match=f"cannot reach tcp://127.0.0.1:{port}"):
        table.position()
    table.close()
    table.close()  # idempotent


def test_a_late_reply_to_a_request_given_up_does_not_answer_the_next(
    turntable, drive, world, clock
):
    world.move("turntable", 33.5)
    clock.sleep(10.0)
    # the status read's every try goes unanswered in time; its last reply comes late,
    # just before the answer to the position read that follows
    drive.faults.drop_next(2)
    drive.faults.late_next(1)
    with pytest.raises(DeviceTimeout, match="gave up after 3 tries"):
        turntable.status()
    assert turntable.position() == pytest.approx(33.5, abs=0.01)
    assert drive.faults.late == 1
