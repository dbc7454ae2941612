"""The laser unit's driver against the fake NXT brick, over both real transports:
pyusb (with the fake brick as its backend) and a pty speaking Bluetooth framing."""

import pytest

from drivers import open_device
from drivers.errors import DeviceError, DeviceFault, DeviceTimeout, MotionStalled, ProtocolError
from drivers.interfaces import Axis, LaserUnit
from rig.clock import VirtualClock
from rig.config import RigConfig
from rig.devices import Retry
from sim.peers.nxt import FakeNxtBrick, FakeNxtUsbBackend, NxtSerialPeer
from sim.world import World

RETRY = Retry(timeout_s=0.05, retries=2, backoff_s=0.01)


@pytest.fixture
def world():
    return World(RigConfig(), VirtualClock())


@pytest.fixture
def brick(world):
    return FakeNxtBrick(world)


def _section(world, **device):
    """The world's laser section with its NXT device changed as given."""
    laser = world.config.laser
    return laser.model_copy(update={"device": laser.device.model_copy(update=device)})


@pytest.fixture(params=["usb", "serial"])
def laser(request, world, brick):
    """An ``NxtLaser`` on the fake brick over one transport; closed afterwards."""
    if request.param == "usb":
        section = _section(world, transport="usb", retry=RETRY)
        backend = FakeNxtUsbBackend(brick)
        driver = open_device("laser", section, clock=world.clock, usb_backend=backend)
        yield driver
        driver.close()
    else:
        with NxtSerialPeer(brick) as peer:
            section = _section(world, transport="serial", serial_port=peer.port, retry=RETRY)
            driver = open_device("laser", section, clock=world.clock)
            yield driver
            driver.close()


def test_satisfies_the_interfaces(laser):
    assert isinstance(laser, LaserUnit)
    assert isinstance(laser.tilt, Axis)


def _move(laser, deg: float) -> float:
    laser.tilt.move_to(deg)
    return laser.tilt.wait_until_settled()


def test_device_name_says_which_transport(laser):
    assert laser.device.startswith("laser brick (")
    assert ("usb 0694:0002" in laser.device) or ("serial /dev/" in laser.device)


def test_battery_check_passes_and_reports_mv(laser, brick):
    brick.faults.battery_mv = 7900
    assert laser.check_battery() == 7900


def test_low_battery_is_a_fault_naming_both_voltages(laser, brick):
    brick.faults.battery_mv = 6100
    with pytest.raises(DeviceFault, match=r"battery at 6100 mV, below the minimum 6500 mV") as info:
        laser.check_battery()
    assert info.value.device == laser.device


def test_laser_switch_reaches_the_world(laser, world):
    laser.set_laser(True)
    assert world.snapshot().laser_on
    assert laser.laser_is_on()
    laser.set_laser(False)
    assert not world.snapshot().laser_on
    assert not laser.laser_is_on()


def test_a_second_mount_has_its_diode_on_the_third_output():
    """Mount 1's diode on output A (motor C, laser B here): lighting it darkens
    mount 0's, and the world's sheet comes from mount 1."""
    config = RigConfig().model_copy(deep=True)
    device = config.laser.device.model_copy(update={"motor_port": "C", "retry": RETRY})
    laser_section = config.laser.model_copy(
        update={"mount_theta_deg": (45.0, 20.0), "device": device}
    )
    world = World(config.model_copy(update={"laser": laser_section}), VirtualClock())
    brick = FakeNxtBrick(world)
    driver = open_device(
        "laser", laser_section, clock=world.clock, usb_backend=FakeNxtUsbBackend(brick)
    )
    try:
        driver.set_laser(True, mount=1)
        snap = world.snapshot()
        assert (snap.laser_on, snap.laser_mount) == (True, 1)
        assert driver.laser_is_on(mount=1) and not driver.laser_is_on(mount=0)
        assert brick.outputs[0].power != 0  # output A
        driver.set_laser(True, mount=0)
        assert (world.snapshot().laser_mount, driver.laser_is_on(mount=1)) == (0, False)
        driver.set_laser(False)
        assert not world.snapshot().laser_on
        with pytest.raises(DeviceError, match=r"mount 2 has no diode; .* mounts 0\.\.1"):
            driver.set_laser(True, mount=2)
    finally:
        driver.close()


def test_move_tilts_the_world_axis_through_the_gear_ratio(laser, world):
    gear = world.config.laser.device.gear_ratio
    laser.tilt.zero()
    t0 = world.clock.now()
    reached = _move(laser, 6.0)
    # 6° of tilt at 1/24 °/motor-degree: 144 motor degrees, whole counts.
    assert reached == pytest.approx(round(6.0 / gear) * gear)
    assert world.position("laser_tilt") == pytest.approx(reached, abs=0.5 * gear)
    assert laser.tilt.position() == pytest.approx(reached)
    # The move took world time: at least distance / speed of the tilt axis.
    assert world.clock.now() - t0 >= 6.0 / world.config.laser.sweep_speed_deg_s - 1e-9
    back = _move(laser, -6.0)
    assert back == pytest.approx(round(-6.0 / gear) * gear)
    assert world.position("laser_tilt") == pytest.approx(back, abs=0.5 * gear)


def test_zero_tilt_makes_the_present_position_zero(laser, world):
    laser.tilt.zero()
    _move(laser, 3.0)
    laser.tilt.zero()
    assert laser.tilt.position() == 0.0
    _move(laser, -2.0)
    assert world.position("laser_tilt") == pytest.approx(
        1.0, abs=world.config.laser.device.gear_ratio
    )


def test_target_outside_the_tilt_range_is_refused_before_anything_moves(laser, brick):
    before = brick.telegrams
    with pytest.raises(DeviceError, match=r"tilt to 40.0°.*outside the unit's tilt range ±30.0°"):
        _move(laser, 40.0)
    assert brick.telegrams == before


def test_stall_is_detected_and_the_motor_stopped(laser, world, brick):
    laser.tilt.zero()
    brick.faults.stall_fraction = 0.5
    with pytest.raises(
        MotionStalled, match=r"stopped at 2\.\d+° tilt .*no progress for 1.0 s"
    ) as info:
        _move(laser, 5.0)
    assert info.value.device == laser.device
    assert world.position("laser_tilt") == pytest.approx(2.5, abs=0.05)
    assert not world.is_moving("laser_tilt")
    assert brick.outputs[brick.tilt_port].power == 0  # the driver braked it


def test_lost_replies_are_retried_and_a_move_is_not_doubled(laser, world, brick):
    laser.tilt.zero()
    brick.faults.lost_replies = 2  # the GET before the move, then the move's own reply
    reached = _move(laser, 4.0)
    assert reached == pytest.approx(4.0, abs=world.config.laser.device.gear_ratio)
    assert world.position("laser_tilt") == pytest.approx(
        4.0, abs=world.config.laser.device.gear_ratio
    )
    assert brick.faults.lost_replies == 0


def test_garbled_replies_are_retried(laser, brick):
    brick.faults.garbled_replies = 2
    brick.faults.battery_mv = 8000
    assert laser.check_battery() == 8000
    assert brick.faults.garbled_replies == 0


def test_garbled_every_time_gives_a_protocol_error_after_the_retries(laser, brick):
    brick.faults.garbled_replies = 100
    with pytest.raises(ProtocolError, match=r"GET_BATTERY_LEVEL .*gave up after 3 tries") as info:
        laser.check_battery()
    assert info.value.device == laser.device
    assert brick.faults.garbled_replies == 97


def test_a_deaf_brick_times_out_after_the_retries(laser, brick):
    brick.faults.deaf = True
    before = brick.telegrams
    with pytest.raises(
        DeviceTimeout, match=r"laser brick .*GET_BATTERY_LEVEL failed: .*no reply"
    ) as info:
        laser.check_battery()
    assert "gave up after 3 tries" in str(info.value)
    assert brick.telegrams - before == 3


def test_a_move_to_a_deaf_brick_fails_naming_the_target(laser, brick):
    brick.faults.deaf = True
    with pytest.raises(DeviceTimeout, match=r"tilt to 2.0° failed"):
        _move(laser, 2.0)


def test_real_usb_path_is_the_same_code_without_a_fake_backend(world):
    # No NXT is plugged into CI: libusb (or its absence) says so, by name.
    with pytest.raises(DeviceError, match=r"laser brick|usb 0694:0002: open failed"):
        open_device("laser", _section(world, retry=RETRY), clock=world.clock)


def test_real_serial_path_names_the_missing_port(world):
    section = _section(world, transport="serial", serial_port="/dev/rfcomm-none", retry=RETRY)
    with pytest.raises(
        DeviceError, match=r"laser brick \(serial /dev/rfcomm-none\): open failed: cannot open"
    ):
        open_device("laser", section, clock=world.clock)


def test_a_tilt_that_crawls_times_out_and_the_motor_is_braked(laser, world, brick):
    # The brick keeps turning (no stall) but far slower than the unit's tilt speed:
    # the wait is bounded by twice the expected move time plus 1 s, not forever.
    laser.tilt.zero()
    laser.tilt.speed_deg_s = 100.0  # expected: 4° in 0.04 s; the world tilts at 1°/s
    t0 = world.clock.now()
    laser.tilt.move_to(4.0)
    with pytest.raises(DeviceTimeout, match=r"tilt to 4.0° failed: still moving at .* after 1.1 s"):
        laser.tilt.wait_until_settled()
    assert world.clock.now() - t0 == pytest.approx(1.1, abs=0.1)
    assert not world.is_moving("laser_tilt")
    assert brick.outputs[brick.tilt_port].power == 0


def test_a_vanished_serial_port_is_a_device_error_naming_the_brick(world, brick):
    """The peer dies (as under kill -9): the tty layer's EIO comes back as a DeviceError."""
    with NxtSerialPeer(brick) as peer:
        section = _section(world, transport="serial", serial_port=peer.port, retry=RETRY)
        driver = open_device("laser", section, clock=world.clock)
        driver.set_laser(True)
    # the peer closed both ends of its pty
    for switch_off in (lambda: driver.set_laser(False), driver.tilt.stop):
        with pytest.raises(DeviceError) as info:
            switch_off()
        assert info.value.device == f"laser brick (serial {peer.port})"
        assert f"serial {peer.port} failed: Input/output error" in info.value.detail
    driver.close()  # logs the failed switch-off; raises nothing raw
