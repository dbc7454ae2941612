"""Degrees of an axis ↔ servo ticks, from the servos' config section."""

import pytest
from hypothesis import given
from hypothesis import strategies as st
from pydantic import ValidationError

from drivers.dynamixel import deg_to_ticks, ticks_to_deg
from rig.devices import DynamixelServos


def test_documented_examples():
    servos = DynamixelServos(ticks_per_rev=4096, gear_ratio=1.0, zero_tick=0)
    assert deg_to_ticks(servos, 90.0) == 1024
    assert ticks_to_deg(servos, 2048) == 180.0
    geared = DynamixelServos(gear_ratio=4.0, zero_tick=1000)
    assert deg_to_ticks(geared, 45.0) == 1000 + 2048
    assert ticks_to_deg(geared, 1000) == 0.0


@given(
    deg=st.floats(0.0, 360.0),
    gear=st.floats(0.25, 50.0),
    zero=st.integers(-100_000, 100_000),
)
def test_round_trip_within_half_a_tick(deg, gear, zero):
    servos = DynamixelServos(gear_ratio=gear, zero_tick=zero)
    half_tick_deg = 0.5 * 360.0 / (servos.ticks_per_rev * gear)
    assert abs(ticks_to_deg(servos, deg_to_ticks(servos, deg)) - deg) <= half_tick_deg + 1e-9


@pytest.mark.parametrize("ids", [(), (1, 1), (253,)])
def test_servo_ids_must_be_unique_bus_ids(ids):
    with pytest.raises(ValidationError, match=r"ids need unique Dynamixel ids in 0\.\.252"):
        DynamixelServos(ids=ids)
