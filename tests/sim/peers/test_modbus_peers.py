"""The Modbus peers spoken to with a plain pymodbus client (the register maps as documented)."""

import os
import select

import pytest
from pymodbus.client import ModbusSerialClient, ModbusTcpClient
from pymodbus.constants import ExcCodes

from rig.clock import VirtualClock
from rig.config import default_rig_config
from rig.devices import LampBankRegisters
from rig.errors import ConfigError
from sim.peers import LampBankPeer, PtyNullModem, ReplyFaults, TurntableDrivePeer
from sim.world import World


@pytest.fixture
def world():
    return World(default_rig_config(), VirtualClock())


@pytest.fixture
def drive(world):
    peer = TurntableDrivePeer(world).start()
    yield peer
    peer.stop()


@pytest.fixture
def client(drive):
    c = ModbusTcpClient("127.0.0.1", port=drive.port, timeout=0.2, retries=0)
    yield c
    c.close()


def int32(value: int) -> list[int]:
    return [(value >> 16) & 0xFFFF, value & 0xFFFF]


def test_go_moves_the_world_and_status_follows(client, world):
    assert client.write_registers(0, int32(4500), device_id=1).isError() is False
    assert client.write_register(5, 1, device_id=1).isError() is False  # go
    assert world.is_moving("turntable")
    status = client.read_holding_registers(4, count=1, device_id=1).registers[0]
    assert status & 0b0001 and not status & 0b0010  # moving, not in position
    world.clock.sleep(10.0)
    regs = client.read_holding_registers(2, count=3, device_id=1).registers
    assert regs[:2] == int32(4500)  # actual position 45.00°
    assert regs[2] == 0b0010  # in position, not homed


def test_home_raises_homed_on_arrival(client, world):
    world.move("turntable", 20.0)
    world.clock.sleep(5.0)
    client.write_register(5, 2, device_id=1)  # home
    world.clock.sleep(5.0)
    assert client.read_holding_registers(4, count=1, device_id=1).registers[0] == 0b1010


def test_the_drive_refuses_what_a_drive_refuses(client, world):
    def code(reply):
        return reply.exception_code if reply.isError() else None

    assert code(client.write_registers(2, [0, 1], device_id=1)) == ExcCodes.ILLEGAL_ADDRESS
    assert code(client.write_register(5, 9, device_id=1)) == ExcCodes.ILLEGAL_VALUE
    assert code(client.write_register(6, 0, device_id=1)) == ExcCodes.ILLEGAL_VALUE
    assert code(client.read_holding_registers(50, count=1, device_id=1)) == ExcCodes.ILLEGAL_ADDRESS
    client.write_registers(0, int32(40000), device_id=1)  # 400°: beyond the axis
    assert code(client.write_register(5, 1, device_id=1)) == ExcCodes.ILLEGAL_VALUE
    assert not world.is_moving("turntable")


def test_drive_fault_bit_and_ignored_go(client, drive, world):
    drive.set_drive_fault(True)
    client.write_registers(0, int32(1000), device_id=1)
    client.write_register(5, 1, device_id=1)
    assert not world.is_moving("turntable")
    assert client.read_holding_registers(4, count=1, device_id=1).registers[0] & 0b0100


def test_rtu_on_a_pty_serves_the_same_map(world):
    with TurntableDrivePeer(world, transport="rtu") as peer:
        client = ModbusSerialClient(peer.serial_port, baudrate=115200, timeout=0.2, retries=0)
        client.write_registers(0, int32(1234), device_id=1)
        client.write_register(5, 1, device_id=1)
        world.clock.sleep(5.0)
        assert client.read_holding_registers(2, count=2, device_id=1).registers == int32(1234)
        client.close()


def test_lamp_bank_coils_sensors_and_dimmers(world):
    layout = LampBankRegisters(coils=3, light_sensors=40, dimming=True, dimmers=10)
    with LampBankPeer(world, registers=layout, faults={"dead_lamps": ["lamp2"]}) as peer:
        client = ModbusTcpClient("127.0.0.1", port=peer.port, timeout=0.2, retries=0)
        client.write_coils(3, [True, False, True, True], device_id=1)  # lamps 0, 2, 3
        assert world.lamps_on == {"lamp0", "lamp2", "lamp3"}
        assert client.read_coils(3, count=8, device_id=1).bits[:8] == [
            True,
            False,
            True,
            True,
            False,
            False,
            False,
            False,
        ]
        # lamp2 is dead: switched on, but its sensor sees nothing
        assert client.read_discrete_inputs(40, count=4, device_id=1).bits[:4] == [
            True,
            False,
            False,
            True,
        ]
        client.write_coil(3, False, device_id=1)
        assert world.lamps_on == {"lamp2", "lamp3"}
        assert client.write_register(12, 400, device_id=1).isError() is False
        assert client.read_holding_registers(12, count=1, device_id=1).registers == [400]
        assert client.write_register(12, 1001, device_id=1).exception_code == ExcCodes.ILLEGAL_VALUE
        client.close()


def test_fault_tables_are_checked(world):
    with pytest.raises(ConfigError, match=r"turntable drive: unknown fault\(s\) \['dead_lamps'\]"):
        TurntableDrivePeer(world, faults={"dead_lamps": ["lamp1"]})
    with pytest.raises(ConfigError, match=r"unknown lamp 'lamp99'; valid are"):
        LampBankPeer(world, faults={"dead_lamps": ["lamp99"]})
    with pytest.raises(ConfigError, match=r"stall_fraction=1.5 must be in \[0, 1\)"):
        TurntableDrivePeer(world, faults={"stall_fraction": 1.5})
    peer = TurntableDrivePeer(world, faults={"stall_fraction": 0.5, "no_reply": 2})
    assert world.turntable.stall_fraction == 0.5
    assert [peer.faults.decide() for _ in range(3)] == ["drop", "drop", "send"]


def test_reply_faults_counts_then_rates():
    faults = ReplyFaults(no_reply=1, garbled=2)
    assert [faults.decide() for _ in range(4)] == ["drop", "garble", "garble", "send"]
    rated = [ReplyFaults(no_reply_rate=0.2, garbled_rate=0.1, seed=7) for _ in range(2)]
    draws = [[f.decide() for _ in range(2000)] for f in rated]
    assert draws[0] == draws[1]  # seeded: reproducible
    assert 0.17 < draws[0].count("drop") / 2000 < 0.23
    assert 0.07 < draws[0].count("garble") / 2000 < 0.13
    with pytest.raises(ConfigError, match="must be a probability"):
        ReplyFaults(no_reply_rate=1.5)
    with pytest.raises(ConfigError, match="must be a count"):
        ReplyFaults(garbled=-1)


def test_null_modem_carries_bytes_both_ways():
    with PtyNullModem() as modem:
        a = os.open(modem.port_a, os.O_RDWR | os.O_NOCTTY)
        b = os.open(modem.port_b, os.O_RDWR | os.O_NOCTTY)
        try:
            os.write(a, b"\x01\x03\xff")
            assert select.select([b], [], [], 1.0)[0]
            assert os.read(b, 16) == b"\x01\x03\xff"
            os.write(b, b"back")
            assert select.select([a], [], [], 1.0)[0]
            assert os.read(a, 16) == b"back"
        finally:
            os.close(a)
            os.close(b)
