"""Interpolation between measured directions, the material arrays, and the bench."""

from __future__ import annotations

import numpy as np
import pytest

from processing.btf import (
    BtfError,
    compress_btf,
    compress_global_svd,
    direction_weights,
    interpolate,
    reconstruct,
    rmse,
)
from processing.btf.synthetic import SyntheticBTF
from rig.geometry import Sampling
from rig.material import MaterialError, btf_from_arrays, btf_to_arrays
from studies.btf_compression import plot, run

N = 12
H2 = Sampling.named("H2").directions


@pytest.fixture(scope="module")
def btf():
    views = H2[::7]  # 12 view slots
    source = SyntheticBTF(N, views, H2)
    return views, np.asarray(source)


@pytest.fixture(scope="module")
def model(btf):
    views, reference = btf
    return compress_btf(reference, view_dirs_deg=views, light_dirs_deg=H2, components=8)


@pytest.mark.parametrize("method", ["nearest", "nearest4", "barycentric"])
def test_interpolation_is_exact_at_measured_directions(model, btf, method):
    views, _ = btf
    for v, li in [(0, 0), (3, 17), (11, 80)]:
        expected = reconstruct(model, view=v, light=li)
        got = interpolate(
            model, view_deg=views[v], light_deg=H2[li], light_method=method, view_method=method
        )
        np.testing.assert_allclose(got, expected, atol=1e-6)


def test_blending_beats_nearest_lookup_at_held_out_lights(btf):
    views, reference = btf
    held = np.array([10, 25, 40, 55])  # inner rings, inside the hull
    kept = np.setdiff1d(np.arange(len(H2)), held)
    model = compress_btf(
        reference[:, kept], view_dirs_deg=views, light_dirs_deg=H2[kept], components=16,
        storage=np.float32,
    )  # fmt: skip
    errors = {}
    for method in ("nearest", "nearest4", "barycentric"):
        errors[method] = np.mean([
            rmse(interpolate(model, view_deg=views[v], light_deg=H2[li], light_method=method),
                 reference[v, li])
            for v in range(len(views)) for li in held
        ])  # fmt: skip
    assert errors["nearest4"] < 0.7 * errors["nearest"]
    assert errors["barycentric"] < 0.7 * errors["nearest"]


@pytest.mark.parametrize("method", ["nearest", "nearest4", "barycentric"])
def test_a_lambertian_texture_interpolates_exactly_between_lights(method):
    """ρ/π · cos θ_l under each measured light (a Lambertian plane): the light's cosine
    is carried, so any light direction gets its own ρ/π · cos θ; weights that sum to
    one (``direction_weights``) blend the measured cosines instead."""
    rng = np.random.default_rng(5)
    albedo = rng.uniform(0.2, 0.9, (N, N, 3))
    cos_l = np.cos(np.radians(H2[:, 0]))
    textures = albedo[None, None] / np.pi * cos_l[None, :, None, None, None]
    model = compress_btf(textures, view_dirs_deg=H2[:1], light_dirs_deg=H2, components=1,
                         storage=np.float32)  # fmt: skip
    for light in ((38.0, 200.0), (52.0, 110.0), (7.0, 300.0), (82.0, 15.0)):
        got = interpolate(model, view_deg=H2[0], light_deg=light, light_method=method)
        truth = albedo / np.pi * np.cos(np.radians(light[0]))
        np.testing.assert_allclose(got, truth, rtol=1e-5, atol=1e-7)
    idx, w = direction_weights(model.light_vectors, (52.0, 110.0), method=method)
    plain = model.blend([0], [1.0], idx, w)
    assert np.abs(plain / (albedo / np.pi * np.cos(np.radians(52.0))) - 1).max() > 0.01


def test_view_blending_stays_between_slots(model, btf):
    views, _ = btf
    between = (views[1] + views[2]) / 2
    blended = interpolate(model, view_deg=between, light_deg=H2[0], view_method="nearest4")
    assert blended.dtype == np.float32
    assert np.all(np.isfinite(blended))
    lo = min(reconstruct(model, view=v, light=0).min() for v in range(len(views)))
    hi = max(reconstruct(model, view=v, light=0).max() for v in range(len(views)))
    assert lo - 1e-3 <= blended.min() and blended.max() <= hi + 1e-3


def test_duplicated_light_directions_interpolate(btf):
    views, reference = btf
    lights = np.vstack([H2[:10], H2[3:4]])  # light 3 measured twice
    stack = np.concatenate([reference[:, :10], reference[:, 3:4]], axis=1)
    model = compress_btf(stack, view_dirs_deg=views, light_dirs_deg=lights, components=4)
    for method in ("nearest", "nearest4", "barycentric"):
        out = interpolate(model, view_deg=views[0], light_deg=H2[3], light_method=method)
        np.testing.assert_allclose(out, reconstruct(model, view=0, light=3), atol=1e-6)


def test_bad_queries_are_named(model):
    with pytest.raises(BtfError, match="method"):
        interpolate(model, view_deg=[0, 0], light_deg=[0, 0], light_method="cubic")
    with pytest.raises(BtfError, match="theta"):
        interpolate(model, view_deg=[0, 0], light_deg=[120, 0])
    with pytest.raises(BtfError, match="view"):
        reconstruct(model, view=99, light=0)


@pytest.mark.parametrize("kind", ["pca", "svd"])
def test_material_arrays_round_trip(btf, model, kind):
    views, reference = btf
    if kind == "svd":
        model = compress_global_svd(reference, view_dirs_deg=views, light_dirs_deg=H2, components=4)
    arrays, attrs = btf_to_arrays(model)
    assert attrs["kind"] == kind
    assert attrs["version"] == 2
    texture = "basis" if kind == "pca" else "eigenmaps"
    assert arrays[texture].dtype == np.float16
    assert arrays["weights"].dtype == np.float32
    back = btf_from_arrays(arrays, attrs)
    assert type(back) is type(model)
    for v, li in [(0, 0), (5, 44)]:
        np.testing.assert_array_equal(
            reconstruct(back, view=v, light=li), reconstruct(model, view=v, light=li)
        )
    with pytest.raises(MaterialError, match="version 99"):
        btf_from_arrays(arrays, {**attrs, "version": 99})
    broken = dict(arrays)
    del broken["weights"]
    with pytest.raises(MaterialError, match="weights"):
        btf_from_arrays(broken, attrs)


@pytest.mark.slow  # a bench
def test_bench_rows(benchmark, tmp_path):
    rows = benchmark.pedantic(
        lambda: run(
            size=8, components=(1, 4), svd_components=(2,), speed_size=16, memory_size=8,
            repeats=1,
        ),
        rounds=1,
    )  # fmt: skip
    kinds = [r["row"] for r in rows]
    assert kinds.count("pca") == 2
    assert kinds.count("svd") == 1
    assert kinds.count("interpolation") == 3
    pca = [r for r in rows if r["row"] == "pca"]
    assert pca[1]["rmse"] < pca[0]["rmse"]
    assert pca[0]["storage_ratio"] > pca[1]["storage_ratio"] > 1
    speed = next(r for r in rows if r["row"] == "speed")
    assert speed["gram_rmse"] == pytest.approx(speed["numpy_svd_rmse"], rel=1e-3)
    memory = next(r for r in rows if r["row"] == "memory")
    assert memory["peak_mib"] > 0
    plot(rows, tmp_path / "btf_bench.png")
    assert (tmp_path / "btf_bench.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
