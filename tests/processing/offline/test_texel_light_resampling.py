"""Per-texel light directions (``processing.offline.texel_light.per_texel_lights``): each
texel's samples, lit from its own directions to near lamps, resampled onto the plan's."""

import numpy as np
import pytest

from processing.offline.texel_light import (
    LampPositions,
    LightResampling,
    lamp_mm,
    light_record,
    per_texel_lights,
)
from processing.offline.texel_resample import texel_directions, texel_resampling
from rig.config import RigConfig
from rig.geometry import direction_vector, texel_centers_mm
from rig.kinematics import lamp_position_mm
from rig.material import Radiometry
from sim.shading import LightSource

SAMPLE_MM, N, RADIUS_MM = 100.0, 16, 650.0
#: The coarse plan's lights: a ring at 15° and one at 45°
NOMINAL = np.array([*[[15, p] for p in (0, 120, 240)], *[[45, p] for p in (0, 90, 180, 270)]],
                   float)  # fmt: skip
#: A tilted Lambertian texel (ρ/π = 1): its value is an analytic function of the light
NORMAL = np.array([0.3, -0.2, 1.0]) / np.linalg.norm([0.3, -0.2, 1.0])


def _lamps(radius_mm: float = RADIUS_MM) -> LampPositions:
    """A lamp ``radius_mm`` from the turntable centre along each nominal light direction."""
    return LampPositions({f"l{i}": radius_mm * direction_vector(t, p)
                          for i, (t, p) in enumerate(NOMINAL)}, "the test's lamps")  # fmt: skip


def _sources(lamps: LampPositions) -> list[np.ndarray]:
    return [lamp_mm(lamps, f"l{i}", arc_deg=0.0, turntable_deg=0.0) for i in range(len(NOMINAL))]


def _stored(sources: list[np.ndarray]) -> np.ndarray:
    """(L, N, N, 1) float32: what the btf stage stores for the tilted Lambertian texel,
    its irradiance divided out on the reference plane: n·l_t · cos θ_centre / cos θ_t."""
    own = [texel_directions(source, SAMPLE_MM, N) for source in sources]
    centre_z = [source[2] / np.linalg.norm(source) for source in sources]
    values = [(o @ NORMAL) * z / o[..., 2] for o, z in zip(own, centre_z, strict=True)]
    return np.stack(values)[..., None].astype(np.float32)


def test_a_texel_sees_the_lamp_where_the_simulator_puts_it():
    config = RigConfig()
    lamps = LampPositions({"lamp3": lamp_position_mm(config, "lamp3", arc_deg=0.0,
                                                     turntable_deg=0.0)}, "nominal")  # fmt: skip
    source = lamp_mm(lamps, "lamp3", arc_deg=40.0, turntable_deg=110.0)
    own = texel_directions(source, SAMPLE_MM, N)
    simulated = LightSource(lamp_position_mm(config, "lamp3", arc_deg=40.0, turntable_deg=110.0),
                            "point", 1.0, 90.0)  # fmt: skip
    xy = texel_centers_mm(SAMPLE_MM, N).reshape(-1, 2)
    dirs, _ = simulated.incident(np.column_stack([xy, np.zeros(len(xy))]))
    np.testing.assert_allclose(own.reshape(-1, 3), dirs, atol=1e-12)
    turn = np.degrees(np.arccos(np.clip(own.reshape(-1, 3) @ own[N // 2, N // 2], -1, 1)))
    assert 3.0 < turn.max() < 9.0  # 650 mm from a 100 mm sample: the direction turns
    assert lamp_mm(lamps, "lampX", arc_deg=0.0, turntable_deg=0.0) is None  # not placed


def test_the_resampled_value_is_nearer_the_truth_at_the_nominal_light():
    """Where a texel's own directions surround the nominal one the blend lands on the
    texel's value there, not its own sample's; outside, the sample is kept as it was."""
    sources = _sources(_lamps())
    textures = _stored(sources)
    moved, record = per_texel_lights(textures, sources, NOMINAL, sample_mm=SAMPLE_MM)
    truth = (direction_vector(NOMINAL[:, 0], NOMINAL[:, 1]) @ NORMAL)[:, None, None]
    raw_error = np.abs(textures[..., 0] - truth)
    error = np.abs(moved[..., 0] - truth)
    kept = moved[..., 0] == textures[..., 0]
    inside = ~kept
    assert inside[:3].all()  # the 15° ring lies inside the hull of every texel's lights
    assert raw_error[inside].mean() > 0.005  # the turn changes the value by ~1 %
    # exact for a Lambertian texel (to float32); blended with weights summing to 1 it
    # would be off by ~0.003, the weights' pull towards the sphere's inside
    assert error[inside].max() < 1e-5
    assert moved.dtype == np.float32 and np.isfinite(moved).all()
    # the 45° ring is the hull's rim: about half its texels were lit from inside it
    assert record.skipped is None and record.captures == len(NOMINAL) * N * N
    assert record.outside == kept.sum() and 0.2 < kept[3:].mean() < 0.8
    assert 0.0 < record.worst_deg < 6.0


def test_an_unknown_blend_names_the_valid_ones():
    own = np.stack([texel_directions(s, SAMPLE_MM, N) for s in _sources(_lamps())])
    with pytest.raises(ValueError, match=r"exact_for = 'cosine': valid are \['constant', "):
        texel_resampling(NOMINAL, own, exact_for="cosine")


def test_lamps_at_infinity_need_no_resampling():
    sources = _sources(_lamps(1e9))
    textures = _stored(sources)
    moved, record = per_texel_lights(textures, sources, NOMINAL, sample_mm=SAMPLE_MM)
    np.testing.assert_allclose(moved, textures, atol=1e-6)
    assert record.worst_deg < 1e-4


def test_one_light_per_view_has_nothing_to_resample_and_says_so():
    sources = _sources(_lamps())[:1]
    textures = _stored(sources)
    moved, record = per_texel_lights(textures, sources, NOMINAL[:1], sample_mm=SAMPLE_MM)
    assert moved is textures and np.isfinite(moved).all()
    assert record.skipped.startswith("1 light(s) per view")
    said = light_record(Radiometry(sources={"irradiance": "nominal"}), [record] * 3)
    assert "light" not in said.sources
    assert said.skipped["light"].startswith("1 light(s) per view")
    assert "every slot keeps each capture at the slot's nominal light direction" in (
        said.skipped["light"])  # fmt: skip


@pytest.mark.parametrize(
    ("sources", "why"),
    [([None, None, None], "directional lamps"), ("below", "at or below some texel's horizon")],
)
def test_lamps_it_cannot_place_above_the_texels_leave_the_slot_as_measured(sources, why):
    if sources == "below":
        sources = [s * np.array([1.0, 1.0, -1.0]) for s in _sources(_lamps())[:3]]
    textures = np.ones((3, N, N, 1), np.float32)
    moved, record = per_texel_lights(textures, sources, NOMINAL[:3], sample_mm=SAMPLE_MM)
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


def test_the_corner_matrices_invert_as_the_pseudo_inverse_does_coplanar_ones_included():
    """The resampling's weights come from each (texel, triangle) corner matrix's inverse,
    by cofactors; nearly coplanar corners (no triangle on the sphere) fall back to the
    pseudo-inverse."""
    from processing.offline.texel_resample import _corner_inverse

    rng = np.random.default_rng(7)
    corners = rng.normal(size=(2000, 3, 3))
    corners /= np.linalg.norm(corners, axis=-1, keepdims=True)
    middle = corners[:5, 0] + corners[:5, 1]
    corners[:5, 2] = middle / np.linalg.norm(middle, axis=-1, keepdims=True)  # on a great circle
    want = np.linalg.pinv(np.swapaxes(corners, -1, -2))
    got = _corner_inverse(corners)
    np.testing.assert_allclose(got[:5], want[:5], rtol=0, atol=1e-12)
    well = np.abs(np.linalg.det(corners)) > 1e-3
    np.testing.assert_allclose(got[well], want[well], rtol=1e-9, atol=1e-9)
    # the weights of a direction reproduce it from the corners
    q = direction_vector(30.0, 40.0)
    w = got[well] @ q
    blended = np.einsum("tk,tkx->tx", w, corners[well])
    np.testing.assert_allclose(blended, np.broadcast_to(q, blended.shape), atol=1e-9)


def test_the_search_near_each_entry_finds_the_triangle_a_search_of_all_would():
    """Each nominal light is looked for in the triangles within two rings of it; a
    search of every triangle of the texel's own directions (here, lamps at 300 mm: turns
    of up to 9°) gives the same blend and rim (on a shared edge either triangle: the
    weight off the edge is 0)."""
    from rig.geometry import Sampling, spherical_triangulation

    nominal = Sampling.named("H1").directions
    n = 6
    own = np.stack([texel_directions(300.0 * direction_vector(*d), SAMPLE_MM, n)
                    for d in nominal])  # fmt: skip
    plan = texel_resampling(nominal, own, exact_for="linear")
    mesh = spherical_triangulation(direction_vector(nominal[:, 0], nominal[:, 1]))
    flip = np.where(mesh.corners[..., 2:] < 0, -1.0, 1.0)  # (T, 3, 1): z mirrored
    for j, (y, x) in [(j, (y, x)) for j in (0, 7, 40, 70, 80) for y in range(n) for x in (0, 5)]:
        corners = own[mesh.owner, y, x].copy()  # (T, 3, 3)
        corners[..., 2:] *= flip
        w = np.stack([np.linalg.lstsq(c.T, direction_vector(*nominal[j]), rcond=None)[0]
                      for c in corners])  # fmt: skip
        best = int(np.argmax(w.min(axis=1)))
        held = w[best].min() >= -1e-9 and not (mesh.corners[best, :, 2] < 0)[w[best] > 1e-9].any()
        assert plan.outside[j, y, x] == (not held)
        if held:
            got, want = np.zeros(len(nominal)), np.zeros(len(nominal))
            np.add.at(got, plan.indices[j, y, x], plan.weights[j, y, x])
            np.add.at(want, mesh.owner[best], np.clip(w[best], 0.0, None))
            np.testing.assert_allclose(got, want, atol=1e-9)
