"""Round trips over many shapes: what a writer accepts, its reader gives back exactly,
in the format's dtypes (float32 maps, uint8 codes, bool masks)."""

import numpy as np
import zarr
from hypothesis import given
from hypothesis import strategies as st

from rig.material import Mdf, PsView, read_mdf, read_ps, write_mdf, write_ps


def _group():
    return zarr.open_group(zarr.storage.MemoryStore(), mode="w", zarr_format=3)


@given(n=st.integers(1, 9), channels=st.sampled_from([1, 3]), seed=st.integers(0, 2**16),
       dtype=st.sampled_from([np.float32, np.float64]))  # fmt: skip
def test_ps_maps_come_back_as_float32(n, channels, seed, dtype):
    rng = np.random.default_rng(seed)
    normals = rng.normal(size=(n, n, 3)) + np.array([0.0, 0.0, 3.0])
    normals /= np.linalg.norm(normals, axis=-1, keepdims=True)
    valid = rng.uniform(size=(n, n)) > 0.5
    view = PsView(
        "v", normals.astype(dtype), rng.uniform(0, 2, (n, n, channels)).astype(dtype), valid,
        rng.integers(0, 6, (n, n)).astype(np.uint8), rng.normal(size=(n, n)).astype(dtype),
        view_deg=(float(rng.uniform(0, 90)), float(rng.uniform(0, 360))),
    )  # fmt: skip
    g = _group()
    write_ps(g, [view])
    got = read_ps(g)["v"]
    for name in ("normals", "albedo", "height_mm"):
        assert getattr(got, name).dtype == np.float32
        np.testing.assert_array_equal(getattr(got, name), getattr(view, name).astype(np.float32))
    assert got.valid.dtype == bool and got.reason.dtype == np.uint8
    np.testing.assert_array_equal(got.valid, valid)
    assert got.view_deg == view.view_deg


@given(views=st.integers(1, 4), n=st.integers(1, 8), seed=st.integers(0, 2**16))
def test_mdf_keeps_unseen_texels(views, n, seed):
    rng = np.random.default_rng(seed)
    distance = rng.uniform(0, 5, (views, n, n))
    distance[rng.uniform(size=distance.shape) < 0.3] = -1.0
    mdf = Mdf(
        distance, rng.uniform([0, 0], [90, 360], (views, 2)),
        np.where(distance < 0, 3, 0), rng.integers(0, 9, distance.shape),
    )  # fmt: skip
    g = _group()
    write_mdf(g, mdf)
    got = read_mdf(g)
    np.testing.assert_array_equal(got.distance_mm, distance.astype(np.float32))
    assert got.distance_mm.dtype == np.float32 and got.count.dtype == np.uint8
    np.testing.assert_array_equal(got.coverage(), (distance >= 0).mean(axis=(1, 2)))
