"""Ray-cast ground truth: MDF, heights and normals against closed forms."""

import numpy as np
import pytest

from rig.geometry import texel_centers_mm
from sim import Simulator
from sim.samples import height_normals
from tests.sim.sim_scenes import small_scene


@pytest.fixture(scope="module")
def flat_sim():
    sim = Simulator(small_scene("flat", sample={"generator": "flat", "depth_mm": 2.5}))
    yield sim
    sim.close()


@pytest.mark.parametrize(("theta", "phi"), [(0, 0), (30, 45), (60, 200), (75, 300)])
def test_flat_recess_mdf_is_depth_over_cos(flat_sim, theta, phi):
    mdf = flat_sim.mdf_truth((theta, phi), 32)
    d = 2.5 / np.cos(np.deg2rad(theta))
    xy = texel_centers_mm(100.0, 32)
    # Rays that reach the floor before leaving under a recess wall.
    horiz = d * np.sin(np.deg2rad(theta))
    v = horiz * np.array([np.cos(np.deg2rad(phi)), np.sin(np.deg2rad(phi))])
    inside = np.all(np.abs(xy - v) < 50.0 - 1e-6, axis=-1)
    np.testing.assert_allclose(mdf[inside], d, atol=1e-4)
    assert mdf.dtype == np.float32
    # Near the wall the ray meets the wall first: a shorter, positive distance.
    assert np.all((mdf[~inside] > 0) & (mdf[~inside] < d + 1e-4))


def test_mdf_is_minus_one_where_nothing_is_hit():
    # A weave whose recess is open underneath does not exist; but a ray that
    # leaves the scene does: look along the plate from far outside.
    with Simulator(small_scene("weave")) as sim:
        mdf = sim.mdf_truth((40, 0), 24)
        assert mdf.min() >= 0  # every texel ray ends on yarn or floor
        # The weave is not a height field: the MDF differs from −h/cosθ.
        texel = sim.texel_truth(24, rays=1)  # both along the texel centres' rays
        frontal = sim.mdf_truth((0, 0), 24)
        np.testing.assert_allclose(frontal, -texel.height, atol=1e-4)


def test_texel_height_and_normals_match_the_height_field():
    n = 40
    with Simulator(small_scene("bumps", params={"grid": 257})) as sim:
        t = sim.texel_truth(n, rays=1)  # the texel centres: the height field's values there
        h = sim.model.sample.height
    xy = texel_centers_mm(100.0, n).reshape(-1, 2)
    # The mesh is a 257² tessellation of h: heights agree to the chord error.
    np.testing.assert_allclose(t.height.reshape(-1), h(xy[:, 0], xy[:, 1]), atol=0.02)
    exact = height_normals(h, xy[:, 0], xy[:, 1])
    cos = np.sum(t.normals.reshape(-1, 3) * exact, axis=1)
    assert np.degrees(np.arccos(np.clip(cos, -1, 1))).max() < 1.0
    assert np.all(t.part == 2)


def _even_cell_lengths(lo, hi, period):
    """Lengths of [lo, hi] in cells ⌊x / period⌋ even and odd (closed form)."""
    edges = np.arange(np.floor(lo / period), np.ceil(hi / period) + 1) * period
    cuts = np.clip(edges, lo, hi)
    lengths, cells = np.diff(cuts), np.floor(edges[:-1] / period).astype(int)
    return lengths[cells % 2 == 0].sum(), lengths[cells % 2 == 1].sum()


def _checker_footprint(n, sample_mm, period, a, b):
    """(n, n) exact mean of the checker albedo over each texel's square."""
    step = sample_mm / n
    xs = [_even_cell_lengths(-sample_mm / 2 + c * step, -sample_mm / 2 + (c + 1) * step, period)
          for c in range(n)]  # fmt: skip
    ys = [_even_cell_lengths(sample_mm / 2 - (r + 1) * step, sample_mm / 2 - r * step, period)
          for r in range(n)]  # fmt: skip
    frac_a = np.array([[(ey * ex + oy * ox) / step**2 for ex, ox in xs] for ey, oy in ys])
    return frac_a * a + (1 - frac_a) * b


def test_texel_truth_is_the_mean_over_the_texel_footprint():
    # Checker edges every 7.5 mm cross every other 5 mm texel through its middle: the
    # texel's truth is the area-weighted mix of the two albedos, not the centre's value.
    a, b, period, n = 0.8, 0.2, 7.5, 20
    materials = {"paint": {"albedo": {"kind": "checker", "rgb_a": [a] * 3, "rgb_b": [b] * 3,
                                      "period_mm": period}}}  # fmt: skip
    sample = {"generator": "flat", "depth_mm": 2.5, "materials": ["paint"]}
    with Simulator(small_scene("flat", sample=sample, materials=materials)) as sim:
        exact = _checker_footprint(n, sim.model.sample_mm, period, a, b)
        btf = sim.btf_truth((0, 0), (0, 0), n)
        texel = sim.texel_truth(n)
        point = sim.btf_truth((0, 0), (0, 0), n, rays=1)
    np.testing.assert_allclose(btf * np.pi, exact[..., None].repeat(3, -1), rtol=1e-5)
    np.testing.assert_allclose(texel.albedo[..., 0], exact, rtol=1e-5)
    np.testing.assert_allclose(np.linalg.norm(texel.normals, axis=-1), 1, atol=1e-6)
    assert np.all(texel.part == 2)
    assert np.abs(point * np.pi - exact[..., None]).max() > 0.2  # the centre ray aliases


@pytest.mark.parametrize("rays", [0, -2, 1.5])
def test_footprint_rays_must_be_a_positive_integer(flat_sim, rays):
    with pytest.raises(ValueError, match="rays per texel side"):
        flat_sim.btf_truth((0, 0), (0, 0), 8, rays=rays)


def test_btf_truth_is_lambertian_on_flat(flat_sim):
    btf = flat_sim.btf_truth((30, 0), (45, 90), 16)
    # the border texels' footprints reach the recess wall (1.4 mm of 6.25 mm at 30°)
    np.testing.assert_allclose(btf[1:-1, 1:-1], 0.7 / np.pi * np.cos(np.deg2rad(45)), rtol=1e-6)


def test_truth_camera_fields(bumps_sim):
    t = bumps_sim.truth("cam3", 20.0, arc_deg=50.0, lamps=["lamp2"])
    assert t.mask.any() and (~t.mask).any()
    assert set(np.unique(t.part)) == {-1, 0, 1, 2} or set(np.unique(t.part)) == {-1, 0, 2}
    assert np.all(t.height[t.mask] <= 1e-6)
    np.testing.assert_allclose(np.linalg.norm(t.normals[t.mask], axis=-1), 1, atol=1e-5)
    assert t.lit["lamp2"].dtype == bool
