"""Fixtures: a simulated world in virtual time and the Modbus peers on real transports."""

import pytest

from rig.devices import ModbusConnection, ModbusDrive, Retry

# Short real-time I/O timeouts (pymodbus waits in real time); backoff on the virtual clock.
FAST_RETRY = Retry(timeout_s=0.2, retries=2, backoff_s=0.01)


@pytest.fixture(params=["tcp", "rtu"])
def transport(request):
    return request.param


def _connection_to(
    peer, transport: str, device: ModbusConnection = ModbusDrive(), retry: Retry = FAST_RETRY
) -> ModbusConnection:
    """``device`` (a drive or lamp bank section) reaching ``peer``: same driver, another port."""
    if transport == "tcp":
        where = {"protocol": "tcp", "host": "127.0.0.1", "port": peer.port}
    else:
        where = {"protocol": "rtu", "serial_port": peer.serial_port}
    return device.model_copy(update={**where, "retry": retry})


@pytest.fixture
def connection_to():
    """``connection_to(peer, transport, device)`` → ``device`` reaching a peer."""
    return _connection_to
