"""Degrees of the light arc ↔ servo ticks, from the rig config."""

import pytest
from hypothesis import given
from hypothesis import strategies as st
from pydantic import ValidationError

from rig.config import LightArc


def test_documented_examples():
    arc = LightArc(servo_ticks_per_rev=4096, servo_gear_ratio=1.0, servo_zero_tick=0)
    assert arc.arc_deg_to_ticks(90.0) == 1024
    assert arc.ticks_to_arc_deg(2048) == 180.0
    geared = LightArc(servo_gear_ratio=4.0, servo_zero_tick=1000)
    assert geared.arc_deg_to_ticks(45.0) == 1000 + 2048
    assert geared.ticks_to_arc_deg(1000) == 0.0


@given(
    deg=st.floats(0.0, 360.0),
    gear=st.floats(0.25, 50.0),
    zero=st.integers(-100_000, 100_000),
)
def test_round_trip_within_half_a_tick(deg, gear, zero):
    arc = LightArc(servo_gear_ratio=gear, servo_zero_tick=zero)
    half_tick_deg = 0.5 * 360.0 / (arc.servo_ticks_per_rev * gear)
    assert abs(arc.ticks_to_arc_deg(arc.arc_deg_to_ticks(deg)) - deg) <= half_tick_deg + 1e-9


@pytest.mark.parametrize("ids", [(), (1, 1), (253,)])
def test_servo_ids_must_be_unique_bus_ids(ids):
    with pytest.raises(ValidationError, match=r"servo_ids need unique Dynamixel ids in 0\.\.252"):
        LightArc(servo_ids=ids)
