"""Fixtures: a simulated world in virtual time and the Modbus peers on real transports."""

import pytest

from rig.clock import VirtualClock
from rig.config import default_rig_config
from rig.connections import ModbusConnection, Retry
from sim.world import World

# Short real-time I/O timeouts (pymodbus waits in real time); backoff on the virtual clock.
FAST_RETRY = Retry(timeout_s=0.2, retries=2, backoff_s=0.01)


@pytest.fixture
def clock():
    return VirtualClock()


@pytest.fixture
def world(clock):
    return World(default_rig_config(), clock)


@pytest.fixture(params=["tcp", "rtu"])
def transport(request):
    return request.param


def _connection_to(peer, transport: str, retry: Retry = FAST_RETRY) -> ModbusConnection:
    """The connection a driver needs to reach ``peer``: same driver, another port."""
    if transport == "tcp":
        return ModbusConnection(protocol="tcp", host="127.0.0.1", port=peer.port, retry=retry)
    return ModbusConnection(protocol="rtu", serial_port=peer.serial_port, retry=retry)


@pytest.fixture
def connection_to():
    """``connection_to(peer, transport)`` → the ``ModbusConnection`` reaching a peer."""
    return _connection_to
