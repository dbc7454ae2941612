"""The lamp-bank driver against the simulated bank, over TCP and RTU (pty)."""

import pytest
from pymodbus.client import ModbusTcpClient

from drivers.errors import DeviceError, DeviceFault, DeviceTimeout
from drivers.interfaces import LampBank
from drivers.modbus import ModbusLampBank
from drivers.registry import open_device
from rig.devices import LampBankRegisters, ModbusLamps
from sim.peers import LampBankPeer

DIMMED = LampBankRegisters(coils=8, light_sensors=100, dimming=True, dimmers=200)


@pytest.fixture
def bank_peer(world, transport):
    peer = LampBankPeer(world, registers=DIMMED, transport=transport).start()
    yield peer
    peer.stop()


@pytest.fixture
def bank(bank_peer, world, clock, transport, connection_to):
    lamps = [lamp.id for lamp in world.config.light_arc.lamps]
    device = ModbusLamps(registers=DIMMED)
    driver = ModbusLampBank(
        connection_to(bank_peer, transport, device), lamp_ids=lamps, clock=clock
    )
    yield driver
    driver.close()


def test_satisfies_the_interface(bank):
    assert isinstance(bank, LampBank)


def test_switch_lights_exactly_the_wanted_lamps(bank, world):
    bank.switch({"lamp1", "lamp5"})
    assert world.snapshot().lamps_on == {"lamp1", "lamp5"}
    assert bank.lamps_on() == {"lamp1", "lamp5"}
    bank.switch({"lamp0"})
    assert world.snapshot().lamps_on == {"lamp0"}
    bank.switch(set())
    assert bank.lamps_on() == frozenset()
    assert world.snapshot().lamps_on == frozenset()


def test_switch_waits_for_the_warmup_on_the_clock(bank, clock):
    t0 = clock.now()
    bank.switch({"lamp2"})
    assert clock.now() - t0 == pytest.approx(0.05)


def test_a_dead_lamp_is_named(bank, bank_peer):
    bank_peer.kill_lamp("lamp3")
    bank.switch({"lamp2"})  # a dead lamp that stays off is no fault
    with pytest.raises(DeviceFault) as err:
        bank.switch({"lamp2", "lamp3"})
    assert "'lamp3' (channel 3)" in str(err.value)
    assert "no light" in str(err.value)
    assert err.value.device == "lamp bank"


def test_a_lamp_lit_while_switched_off_is_named(bank, bank_peer):
    bank_peer.stick_lamp("lamp4")  # a welded relay: its sensor sees light, coil off
    with pytest.raises(DeviceFault, match=r"'lamp4' \(channel 4\) is switched off but still lit"):
        bank.switch({"lamp6"})


def test_dimming_round_trip_and_register_value(bank, bank_peer, transport):
    bank.set_level("lamp2", 0.25)
    assert bank.level("lamp2") == pytest.approx(0.25)
    assert bank.level("lamp3") == pytest.approx(1.0)  # untouched: full scale
    if transport == "tcp":  # ground truth from a plain client: register 200 + 2 = 250/1000
        client = ModbusTcpClient("127.0.0.1", port=bank_peer.port, timeout=0.2, retries=0)
        assert client.read_holding_registers(202, count=1, device_id=1).registers == [250]
        client.close()


def test_bad_requests_name_what_is_valid(bank):
    with pytest.raises(ValueError, match=r"unknown lamp\(s\) \['lamp9'\]; this bank has"):
        bank.switch({"lamp9"})
    with pytest.raises(ValueError, match=r"level 1.5 for 'lamp1' must be in \[0, 1\]"):
        bank.set_level("lamp1", 1.5)


def test_a_bank_without_dimmers_says_so(world, clock, connection_to):
    with LampBankPeer(world) as peer:
        section = world.config.lamp_bank.model_copy(
            update={"device": connection_to(peer, "tcp", world.config.lamp_bank.device)}
        )
        lamp_ids = [lamp.id for lamp in world.config.light_arc.lamps]
        driver = open_device("lamp_bank", section, clock=clock, lamp_ids=lamp_ids)
        with pytest.raises(DeviceError, match="no dimmers"):
            driver.set_level("lamp1", 0.5)
        driver.switch({"lamp7"})
        assert world.snapshot().lamps_on == {"lamp7"}
        driver.close()


def test_lost_and_garbled_replies_are_retried(bank, bank_peer, world):
    bank_peer.faults.drop_next(1)
    bank_peer.faults.garble_next(1)
    bank.switch({"lamp4"})
    assert world.snapshot().lamps_on == {"lamp4"}
    assert (bank_peer.faults.dropped, bank_peer.faults.garbled) == (1, 1)


def test_a_silent_bank_fails_naming_the_operation(bank, bank_peer):
    bank_peer.faults.drop_next(100)
    with pytest.raises(DeviceTimeout, match=r"lamp bank: switch on \['lamp1'\] failed"):
        bank.switch({"lamp1"})
    assert bank_peer.faults.dropped == 3
