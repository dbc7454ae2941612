"""Fixtures: a simulated UR controller on loopback ports and the driver connected to it."""

import pytest

from drivers.ur import UrArm
from rig.devices import Retry, UrController
from sim.peers.ur import UrControllerPeer

# Short real-time socket timeouts; backoff and motion on the virtual clock.
FAST_RETRY = Retry(timeout_s=0.5, retries=2, backoff_s=0.01)


@pytest.fixture
def make_peer(world):
    """``make_peer(**options)`` → a started controller peer, stopped after the test."""
    peers = []

    def make(**options):
        peer = UrControllerPeer(world, **options).start()
        peers.append(peer)
        return peer

    yield make
    for peer in peers:
        peer.stop()


@pytest.fixture
def controller(make_peer):
    return make_peer()


def device_of(peer, **fields) -> UrController:
    """A ``UrController`` section reaching ``peer``."""
    return UrController(
        dashboard_port=peer.dashboard_port,
        realtime_port=peer.realtime_port,
        retry=FAST_RETRY,
        **fields,
    )


@pytest.fixture
def arm(controller, clock):
    driver = UrArm(device_of(controller), clock=clock)
    yield driver
    driver.close()


@pytest.fixture
def ready_arm(arm):
    arm.home()
    return arm
