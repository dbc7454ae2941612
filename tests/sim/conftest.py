"""Shared simulator fixtures (one Simulator per module saves GL contexts)."""

from __future__ import annotations

import pytest
from sim_scenes import small_scene

from sim import Simulator


@pytest.fixture(scope="module")
def bumps_sim():
    sim = Simulator(small_scene("bumps", params={"grid": 65}))
    yield sim
    sim.close()
