"""Every device of a rig served by ``start_peer`` and reached by ``open_device``'s drivers."""

from types import SimpleNamespace

import pytest

from drivers import open_device
from drivers.errors import DeviceError, DeviceFault
from rig.clock import VirtualClock
from rig.config import default_rig_config
from rig.devices import DEVICE_ROLES, Retry
from rig.errors import ConfigError
from sim.peers import register_peer, start_peer
from sim.world import World

FAST = Retry(timeout_s=0.2, retries=1, backoff_s=0.01)


def _connected(world, peers):
    """The world's rig with every device on its peer and short timeouts (real-time I/O)."""
    update = {}
    for role, peer in peers.items():
        section = peer.connect(getattr(world.config, role))
        device = section.device.model_copy(update={"retry": FAST})
        update[role] = section.model_copy(update={"device": device})
    return world.config.model_copy(update=update)


@pytest.fixture
def world():
    return World(default_rig_config(), VirtualClock())


@pytest.fixture
def start(world):
    """``start(role, **options)``: a started peer of the world's rig, stopped afterwards."""
    started = []

    def starting(role, **options):
        peer = start_peer(role, getattr(world.config, role), world, **options)
        started.append(peer)
        return peer

    yield starting
    for peer in reversed(started):
        peer.stop()


@pytest.mark.parametrize("serial", [False, True])
def test_every_role_is_served_and_its_driver_moves_one_world(world, start, serial):
    peers = {role: start(role, serial=serial) for role in DEVICE_ROLES}
    config = _connected(world, peers)
    assert config.turntable.device.protocol == ("rtu" if serial else "tcp")
    assert config.laser.device.transport == "serial"
    clock = world.clock
    lamp_ids = [lamp.id for lamp in config.light_arc.lamps]
    table = open_device("turntable", config.turntable, clock=clock)
    arc = open_device("light_arc", config.light_arc, clock=clock)
    bank = open_device("lamp_bank", config.lamp_bank, clock=clock, lamp_ids=lamp_ids)
    laser = open_device("laser", config.laser, clock=clock)
    try:
        arc.home()
        for axis, target in ((table, 120.0), (arc, 30.0), (laser.tilt, 3.0)):
            axis.move_to(target)
        reached = [axis.wait_until_settled() for axis in (table, arc, laser.tilt)]
        bank.switch({"lamp0", "lamp4"})
        laser.set_laser(True)
        snap = world.snapshot()
    finally:
        for device in (table, arc, bank, laser):
            device.close()
    assert reached == pytest.approx([120.0, 30.0, 3.0], abs=0.1)
    assert (snap.turntable_deg, snap.arc_deg) == pytest.approx((120.0, 30.0), abs=0.1)
    assert snap.laser_tilt_deg == pytest.approx(3.0, abs=0.1)
    assert snap.lamps_on == {"lamp0", "lamp4"} and snap.laser_on


def test_faults_from_a_table_reach_each_peer(world, start):
    peers = {
        "lamp_bank": start("lamp_bank", faults={"dead_lamps": ["lamp1"]}),
        "light_arc": start("light_arc", faults={"hardware_error": {1: 0x20}}),
        "laser": start("laser", faults={"battery_mv": 6000}),
    }
    config = _connected(world, peers)
    lamp_ids = [lamp.id for lamp in config.light_arc.lamps]
    bank = open_device("lamp_bank", config.lamp_bank, clock=world.clock, lamp_ids=lamp_ids)
    arc = open_device("light_arc", config.light_arc, clock=world.clock)
    laser = open_device("laser", config.laser, clock=world.clock)
    try:
        with pytest.raises(DeviceFault, match="'lamp1'"):
            bank.switch({"lamp1"})
        with pytest.raises(DeviceFault, match=r"servo 1.*overload"):
            arc.home()
        with pytest.raises(DeviceFault, match="battery at 6000 mV"):
            laser.check_battery()
    finally:
        for device in (bank, arc, laser):
            device.close()


@pytest.mark.parametrize(
    ("role", "faults", "message"),
    [
        ("laser", {"deaf": True, "on_fire": 1}, r"laser brick: unknown fault\(s\) \['on_fire'\]"),
        ("light_arc", {"hardware_error": {9: 1}}, "dynamixel bus: no servo 9"),
        ("turntable", {"dead_lamps": ["lamp1"]}, r"turntable drive: unknown fault\(s\)"),
    ],
)
def test_a_bad_fault_table_is_named(world, role, faults, message):
    with pytest.raises(ConfigError, match=message):
        start_peer(role, getattr(world.config, role), world, faults=faults)


def test_a_kind_without_a_peer_or_a_driver_is_named(world):
    section = SimpleNamespace(device=SimpleNamespace(kind="canopen"))
    with pytest.raises(
        ConfigError, match=r"turntable.device: no simulated peer for kind 'canopen'"
    ):
        start_peer("turntable", section, world)
    with pytest.raises(DeviceError, match=r"turntable: open failed: no driver for kind 'canopen'"):
        open_device("turntable", section, clock=world.clock)


def test_a_role_and_kind_cannot_be_registered_twice():
    with pytest.raises(ValueError, match="turntable/modbus is registered twice"):
        register_peer("turntable", "modbus")(lambda section, world, **options: None)
    with pytest.raises(ValueError, match=r"unknown role 'camera_arc'"):
        register_peer("camera_arc", "x")
