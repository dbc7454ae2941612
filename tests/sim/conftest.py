"""Shared simulator fixtures (one Simulator per module saves GL contexts)."""

from __future__ import annotations

import pytest

from sim import Simulator
from tests.sim.sim_scenes import small_scene


@pytest.fixture(scope="module")
def bumps_sim():
    sim = Simulator(small_scene("bumps", params={"grid": 65}))
    yield sim
    sim.close()
