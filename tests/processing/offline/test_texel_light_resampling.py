"""Per-texel light directions (``processing.offline.texel_light.per_texel_lights``): each
texel's samples, lit from its own directions to near lamps, resampled onto the plan's."""

import numpy as np
import pytest

from processing.offline.texel_light import (
    LampPositions,
    LightResampling,
    light_record,
    per_texel_lights,
    texel_light_directions,
)
from rig.config import RigConfig
from rig.geometry import direction_vector, texel_centers_mm
from rig.kinematics import lamp_position_mm
from rig.material import Radiometry
from sim.shading import LightSource

SAMPLE_MM, N, RADIUS_MM = 100.0, 16, 650.0
#: The coarse plan's lights: a ring at 15° and one at 45°
NOMINAL = np.array([*[[15, p] for p in (0, 120, 240)], *[[45, p] for p in (0, 90, 180, 270)]],
                   float)  # fmt: skip
#: A tilted Lambertian texel: its value per unit irradiance on the reference plane,
#: ρ n·l / cos θ_l, is an analytic function of the light direction
NORMAL = np.array([0.3, -0.2, 1.0]) / np.linalg.norm([0.3, -0.2, 1.0])


def _lamps(radius_mm: float = RADIUS_MM) -> LampPositions:
    """A lamp ``radius_mm`` from the turntable centre along each nominal light direction."""
    return LampPositions({f"l{i}": radius_mm * direction_vector(t, p)
                          for i, (t, p) in enumerate(NOMINAL)}, "the test's lamps")  # fmt: skip


def _own(lamps: LampPositions) -> list[np.ndarray]:
    return [texel_light_directions(lamps, f"l{i}", sample_mm=SAMPLE_MM, size=N, arc_deg=0.0,
                                   turntable_deg=0.0) for i in range(len(NOMINAL))]  # fmt: skip


def _lit(own: list[np.ndarray]) -> np.ndarray:
    """(L, N, N, 1) float32: the tilted Lambertian texel's value under each light."""
    return np.stack([_lambertian(o) for o in own])[..., None].astype(np.float32)


def _lambertian(light: np.ndarray) -> np.ndarray:
    return (light @ NORMAL) / light[..., 2]


def test_a_texel_sees_the_lamp_where_the_simulator_puts_it():
    config = RigConfig()
    lamps = LampPositions({"lamp3": lamp_position_mm(config, "lamp3", arc_deg=0.0,
                                                     turntable_deg=0.0)}, "nominal")  # fmt: skip
    own = texel_light_directions(lamps, "lamp3", sample_mm=SAMPLE_MM, size=N, arc_deg=40.0,
                                 turntable_deg=110.0)  # fmt: skip
    source = LightSource(lamp_position_mm(config, "lamp3", arc_deg=40.0, turntable_deg=110.0),
                         "point", 1.0, 90.0)  # fmt: skip
    xy = texel_centers_mm(SAMPLE_MM, N).reshape(-1, 2)
    dirs, _ = source.incident(np.column_stack([xy, np.zeros(len(xy))]))
    np.testing.assert_allclose(own.reshape(-1, 3), dirs, atol=1e-12)
    turn = np.degrees(np.arccos(np.clip(own.reshape(-1, 3) @ own[N // 2, N // 2], -1, 1)))
    assert 3.0 < turn.max() < 9.0  # 650 mm from a 100 mm sample: the direction turns
    assert texel_light_directions(lamps, "lampX", sample_mm=SAMPLE_MM, size=N, arc_deg=0.0,
                                  turntable_deg=0.0) is None  # a lamp not placed  # fmt: skip


def test_the_resampled_value_is_nearer_the_truth_at_the_nominal_light():
    """Where a texel's own directions surround the nominal one the blend lands on the
    texel's value there, not its own sample's; outside, the sample is kept as it was."""
    own = _own(_lamps())
    textures = _lit(own)
    moved, record = per_texel_lights(textures, own, NOMINAL)
    truth = _lambertian(direction_vector(NOMINAL[:, 0], NOMINAL[:, 1]))[:, None, None]
    raw_error = np.abs(textures[..., 0] - truth)
    error = np.abs(moved[..., 0] - truth)
    kept = moved[..., 0] == textures[..., 0]
    inside = ~kept
    assert inside[:3].all()  # the 15° ring lies inside the hull of every texel's lights
    assert raw_error[inside].mean() > 0.01  # the turn changes the value by ~1 %
    # exact for a Lambertian texel (to float32); blended on each triangle's own plane
    # it would be off by 0.003 on average, the weights' pull towards the sphere's inside
    assert error[inside].max() < 1e-5
    assert moved.dtype == np.float32 and np.isfinite(moved).all()
    # the 45° ring is the hull's rim: about half its texels were lit from inside it
    assert record.skipped is None and record.captures == len(NOMINAL) * N * N
    assert record.outside == kept.sum() and 0.2 < kept[3:].mean() < 0.8
    assert 0.0 < record.worst_deg < 6.0


def test_lamps_at_infinity_need_no_resampling():
    own = _own(_lamps(1e9))
    textures = _lit(own)
    moved, record = per_texel_lights(textures, own, NOMINAL)
    np.testing.assert_allclose(moved, textures, atol=1e-6)
    assert record.worst_deg < 1e-4


def test_one_light_per_view_has_nothing_to_resample_and_says_so():
    own = _own(_lamps())[:1]
    textures = _lit(own)
    moved, record = per_texel_lights(textures, own, NOMINAL[:1])
    assert moved is textures and np.isfinite(moved).all()
    assert record.skipped.startswith("1 light(s) per view")
    said = light_record(Radiometry(sources={"irradiance": "nominal"}), [record] * 3)
    assert "light" not in said.sources
    assert said.skipped["light"].startswith("1 light(s) per view")
    assert "every slot keeps each capture at the slot's nominal light direction" in (
        said.skipped["light"])  # fmt: skip


@pytest.mark.parametrize(
    ("own", "why"),
    [([None, None, None], "directional lamps"), ("below", "at or below some texel's horizon")],
)
def test_lamps_it_cannot_place_above_the_texels_leave_the_slot_as_measured(own, why):
    if own == "below":
        own = [o * np.array([1.0, 1.0, -1.0]) for o in _own(_lamps())[:3]]
    textures = np.ones((3, N, N, 1), np.float32)
    moved, record = per_texel_lights(textures, own, NOMINAL[:3])
    assert moved is textures and why in record.skipped


def test_the_record_sums_the_slots_and_names_the_lamps_source():
    slots = [LightResampling(10, 100, 2.5), LightResampling(0, 100, 0.0),
             LightResampling(skipped="a lamp at or below some texel's horizon")]  # fmt: skip
    said = light_record(Radiometry(sources={"irradiance": "calibrated lamp positions, s"}), slots)
    assert said.sources["light"] == "calibrated lamp positions, s"
    assert said.skipped["light"].startswith("10 of 200 texel captures outside the hull")
    assert "(up to 2.5° off)" in said.skipped["light"]
    assert "1 of 3 view slots keeps each capture" in said.skipped["light"]
    clean = light_record(Radiometry(sources={"irradiance": "x"}), [LightResampling(0, 100, 0.0)])
    assert "light" not in clean.skipped and clean.sources["light"] == "x"
