"""Fixtures every driver's tests share: the virtual clock and the simulated world on it."""

import pytest

from rig.clock import VirtualClock
from rig.config import default_rig_config
from sim.world import World


@pytest.fixture
def clock():
    return VirtualClock()


@pytest.fixture
def world(clock):
    return World(default_rig_config(), clock)
