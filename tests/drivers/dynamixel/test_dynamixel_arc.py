"""The light-arc driver (dynamixel-sdk) against the simulated Protocol 2.0 bus on a pty."""

import re

import pytest

from drivers.dynamixel import DynamixelArc, DynamixelBus
from drivers.errors import DeviceError, DeviceFault, DeviceTimeout, MotionStalled, ProtocolError
from drivers.interfaces import Axis
from rig.clock import VirtualClock
from rig.config import default_rig_config
from rig.devices import DynamixelServos, Retry
from rig.errors import KinematicsError
from sim.peers import DynamixelBusPeer

FAST_RETRY = Retry(timeout_s=0.2, retries=2, backoff_s=0.01)
AXIS = default_rig_config().light_arc.axis
GEARED = DynamixelServos(ids=(1, 2), gear_ratio=4.0, zero_tick=1000)


@pytest.fixture
def bus(world):
    peer = DynamixelBusPeer(world, servos=GEARED).start()
    yield peer
    peer.stop()


def _servos(peer, **update):
    update = {"serial_port": peer.serial_port, "retry": FAST_RETRY, **update}
    return GEARED.model_copy(update=update)


@pytest.fixture
def arc(bus, clock):
    driver = DynamixelArc(_servos(bus), axis=AXIS, clock=clock)
    driver.enable()
    yield driver
    driver.close()


def test_satisfies_the_interface(arc):
    assert isinstance(arc, Axis)


def test_enable_loads_the_profile_from_the_axis_limits(arc, bus):
    # 20°/s of the arc at 4 servo turns per arc turn = 13.33 rpm = 58 × 0.229 rpm;
    # 40°/s² = 1600 rev/min² = 7.46 × 214.577 rev/min² → 7.
    assert arc.profile() == (58, 7)
    for servo in bus.servos.values():
        assert int.from_bytes(servo.table[112:116], "little") == 58
        assert int.from_bytes(servo.table[108:112], "little") == 7
        assert servo.table[64] == 1  # torque on


def test_move_drives_both_servos_to_one_goal(arc, bus, world, clock):
    t0 = clock.now()
    arc.move_to(45.0)
    expected_goal = 1000 + round(45.0 / 360.0 * 4.0 * 4096)  # zero tick + gearing
    for servo in bus.servos.values():
        assert int.from_bytes(servo.table[116:120], "little", signed=True) == expected_goal
    settled = arc.wait_until_settled()
    assert settled == pytest.approx(45.0, abs=360.0 / (4 * 4096))
    assert world.position("arc") == pytest.approx(45.0, abs=0.01)
    expected = float(world.config.light_arc.axis.move_time_s(45.0))
    assert expected - 1e-6 <= clock.now() - t0 <= expected + 0.05 + 1e-6


def test_position_follows_the_world_mid_move(arc, world, clock):
    arc.move_to(90.0)
    clock.sleep(1.5)
    assert arc.position() == pytest.approx(world.position("arc"), abs=0.03)
    assert 0.0 < arc.position() < 90.0


def test_lost_and_garbled_status_packets_are_retried(arc, bus, world, clock):
    world.move("arc", 30.0)
    clock.sleep(10.0)
    bus.faults.drop_next(1)
    assert arc.position() == pytest.approx(30.0, abs=0.03)
    bus.faults.garble_next(1)
    assert arc.position() == pytest.approx(30.0, abs=0.03)
    assert (bus.faults.dropped, bus.faults.garbled) == (1, 1)


def test_a_silent_bus_fails_after_the_retries(arc, bus):
    bus.faults.drop_next(100)
    with pytest.raises(DeviceTimeout, match=r"light arc: position failed.*no status packet"):
        arc.position()


def test_a_garbling_bus_fails_as_a_protocol_error(arc, bus):
    bus.faults.garble_next(100)
    with pytest.raises(ProtocolError, match=r"light arc.*corrupt status packet.*gave up after 3"):
        arc.position()


def test_stall_names_target_and_stop(arc, bus):
    bus.set_stall(0.5)
    arc.move_to(60.0)
    with pytest.raises(MotionStalled) as err:
        arc.wait_until_settled()
    assert "light arc" in str(err.value)
    assert "60.00°" in str(err.value)
    assert re.search(r"stopped at 30\.0\d°", str(err.value))  # half-way, within a tick


def test_hardware_error_names_the_servo_and_reboot_recovers(arc, bus, world):
    arc.move_to(20.0)
    bus.set_hardware_error(2, 0x20)  # overload
    with pytest.raises(DeviceFault, match=r"servo 2 reports hardware error 0x20 \(overload\)"):
        arc.wait_until_settled()
    with pytest.raises(DeviceFault, match=r"servo 2.*overload"):
        arc.enable()
    arc.reboot()
    arc.enable()
    arc.move_to(20.0)
    assert arc.wait_until_settled() == pytest.approx(20.0, abs=0.03)


def test_alert_bit_on_a_single_read_is_a_device_fault(arc, bus):
    bus.set_hardware_error(1, 0x04)  # overheating
    arc.close()  # one owner per bus: the raw bus below takes it over
    raw = DynamixelBus(arc.servos, device="light arc", clock=VirtualClock())
    with pytest.raises(DeviceFault, match=r"servo 1 .*0x04 \(overheating\)"):
        raw.read(1, 132, 4, operation="read")
    raw.close()


def test_servo_refusals_are_clear_and_not_retried(arc):
    bus = arc._bus
    with pytest.raises(DeviceError, match="servo 1 answered error 7: access error"):
        bus.write(1, 132, 4, 0, operation="write present position")
    with pytest.raises(DeviceError, match="servo 1 answered error 7"):
        bus.write(1, 11, 1, 3, operation="set mode with torque on")


def test_goal_outside_the_position_mode_range_is_refused(world, clock):
    with DynamixelBusPeer(world, servos=GEARED, operating_mode=3) as peer:
        driver = DynamixelArc(_servos(peer), axis=AXIS, clock=clock)
        driver.enable()  # reads limits 0..4095 from the servos
        with pytest.raises(
            DeviceError, match=r"goal tick 5096, outside servo 1's range \[0, 4095\]"
        ):
            driver.move_to(90.0)
        driver.close()


def test_bad_requests(arc, bus, clock):
    with pytest.raises(KinematicsError, match=r"400.0° is outside .*\[0.0°, 360.0°\]"):
        arc.move_to(400.0)
    arc.close()  # one owner per bus
    fresh = DynamixelArc(_servos(bus), axis=AXIS, clock=clock)
    with pytest.raises(DeviceError, match=r"call enable\(\) first"):
        fresh.move_to(10.0)
    fresh.close()
    fresh.close()  # idempotent


def test_a_missing_port_is_named(clock):
    servos = GEARED.model_copy(update={"serial_port": "/dev/does-not-exist", "retry": FAST_RETRY})
    with pytest.raises(DeviceError, match="cannot open serial port '/dev/does-not-exist'"):
        DynamixelArc(servos, axis=AXIS, clock=clock)


def test_a_servo_missing_from_the_bus_times_out(world, clock):
    with DynamixelBusPeer(world, servos=GEARED.model_copy(update={"ids": (1,)})) as peer:
        driver = DynamixelArc(_servos(peer), axis=AXIS, clock=clock)  # config says servos 1 and 2
        with pytest.raises(DeviceTimeout, match="servo 2: no status packet"):
            driver.enable()
        driver.close()


def test_a_vanished_bus_is_a_device_error_naming_the_port(arc, bus):
    """The adapter unplugged (the peer's pty closed): the SDK's termios/OS error becomes a
    ``DeviceError`` naming the light arc and its port, for the daemon to pause on."""
    port = bus.serial_port
    bus.stop()
    with pytest.raises(DeviceError, match=re.escape(f"serial port {port!r} failed")) as caught:
        arc.stop()
    assert caught.value.device == "light arc"


def test_a_reply_is_waited_for_not_polled_for(bus, clock):
    # The SDK reads the port until a status packet or its timeout comes. A dropped reply
    # costs the 0.2 s timeout: reads that wait for their bytes make ~100 of them, a
    # non-blocking port tens of thousands (a spin that was half a simulated session's CPU).
    driver = DynamixelBus(_servos(bus), device="light arc", clock=clock)
    try:
        port, reads = driver.port.ser, []
        read = port.read
        port.read = lambda size=1: reads.append(size) or read(size)
        bus.faults.drop_next(1)
        assert driver.ping(1) > 0
        assert bus.faults.dropped == 1
        assert 0 < len(reads) < 1000
    finally:
        driver.close()
