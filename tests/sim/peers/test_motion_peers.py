"""All motion peers at once, reached by unchanged drivers through a rewritten rig config."""

import pytest
from rig.connections import Retry

from drivers.dynamixel import DynamixelArc
from drivers.errors import DeviceFault
from drivers.modbus import ModbusLampBank, ModbusTurntable
from rig.clock import VirtualClock
from rig.config import default_rig_config
from rig.errors import ConfigError
from sim.peers import start_motion_peers
from sim.world import World

FAST = Retry(timeout_s=0.2, retries=1, backoff_s=0.01)


def _fast(config):
    """The same rig with short timeouts (pymodbus and the SDK wait in real time)."""
    tt, lb, arc = config.turntable, config.lamp_bank, config.light_arc
    return config.model_copy(
        update={
            "turntable": tt.model_copy(
                update={"drive": tt.drive.model_copy(update={"retry": FAST})}
            ),
            "lamp_bank": lb.model_copy(
                update={"connection": lb.connection.model_copy(update={"retry": FAST})}
            ),
            "light_arc": arc.model_copy(
                update={"servos": arc.servos.model_copy(update={"retry": FAST})}
            ),
        }
    )


@pytest.mark.parametrize("transport", ["tcp", "rtu"])
def test_drivers_from_the_rewritten_config_move_one_world(transport):
    clock = VirtualClock()
    world = World(default_rig_config(), clock)
    with start_motion_peers(world, transport=transport) as peers:
        config = _fast(peers.rig_config(world.config))
        assert config.turntable.drive.protocol == transport
        assert config.light_arc.servos.serial_port == peers.light_arc.serial_port
        table = ModbusTurntable.from_config(config, clock=clock)
        bank = ModbusLampBank.from_config(config, clock=clock)
        arc = DynamixelArc.from_config(config, clock=clock)
        arc.enable()
        table.move_to(120.0)
        arc.move_to(30.0)
        table.wait_until_settled()
        arc.wait_until_settled()
        bank.switch({"lamp0", "lamp4"})
        snap = world.snapshot()
        assert snap.turntable_deg == pytest.approx(120.0)
        assert snap.arc_deg == pytest.approx(30.0, abs=0.1)
        assert snap.lamps_on == {"lamp0", "lamp4"}
        for driver in (table, bank, arc):
            driver.close()


def test_faults_from_a_table_reach_each_peer():
    clock = VirtualClock()
    world = World(default_rig_config(), clock)
    faults = {"lamp_bank": {"dead_lamps": ["lamp1"]}, "light_arc": {"hardware_error": {1: 0x20}}}
    with start_motion_peers(world, faults=faults) as peers:
        config = _fast(peers.rig_config(world.config))
        bank = ModbusLampBank.from_config(config, clock=clock)
        with pytest.raises(DeviceFault, match="'lamp1'"):
            bank.switch({"lamp1"})
        arc = DynamixelArc.from_config(config, clock=clock)
        with pytest.raises(DeviceFault, match=r"servo 1.*overload"):
            arc.enable()
        bank.close()
        arc.close()


def test_an_unknown_peer_in_the_fault_table_is_named():
    world = World(default_rig_config(), VirtualClock())
    with pytest.raises(ConfigError, match=r"unknown peer\(s\) \['camera_arc'\]"):
        start_motion_peers(world, faults={"camera_arc": {}})


def test_a_peer_that_fails_to_start_stops_the_others():
    world = World(default_rig_config(), VirtualClock())
    with pytest.raises(ConfigError, match="dynamixel bus: no servo 9"):
        start_motion_peers(world, faults={"light_arc": {"hardware_error": {9: 1}}})
    # the leak check (conftest) fails this test if the Modbus servers were left running
