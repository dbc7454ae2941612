"""Hard cases through the whole BTF path: compress → material arrays → reconstruct → interpolate.

``test_btf_pca.py`` checks single view slots (rank 0, fewer lights than
components, duplicated lights, any stack by hypothesis); here the same cases sit
inside a BTF and go through every later stage, where a rank-0 slot, a
duplicated direction or a one-light table could produce NaN or crash.
"""

from __future__ import annotations

import numpy as np
import pytest

from processing.btf import (
    BtfError,
    compress_btf,
    compress_global_svd,
    interpolate,
    reconstruct,
)
from rig.geometry import Sampling
from rig.material import btf_from_arrays, btf_to_arrays

N = 8
H2 = Sampling.named("H2").directions
VIEWS = np.array([[0.0, 0.0], [30.0, 0.0], [30.0, 120.0], [30.0, 240.0]])


def _btf(n_lights: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rng.random((len(VIEWS), n_lights, N, N, 3)).astype(np.float32)


def _finite(*arrays) -> bool:
    return all(np.all(np.isfinite(np.asarray(a, dtype=np.float64))) for a in arrays)


def test_constant_and_black_views_survive_every_stage():
    btf = _btf(12)
    btf[1] = 0.3  # a constant (rank-0) view: no light changes anything
    btf[2] = 0.0  # a black view (a dead camera, a fully shadowed slot)
    model = compress_btf(btf, view_dirs_deg=VIEWS, light_dirs_deg=H2[:12], components=4)
    assert model.rank[1] == 0 and model.rank[2] == 0
    assert model.rank[0] == 4
    arrays, attrs = btf_to_arrays(model)
    back = btf_from_arrays(arrays, attrs)
    for view, value in ((1, 0.3), (2, 0.0)):
        out = reconstruct(back, view=view, light=5)
        assert _finite(out)
        np.testing.assert_allclose(out, value, atol=1e-3)  # float16 mean
    # Blending a rank-0 slot with a full one stays between them, finite.
    between = interpolate(back, view_deg=(15.0, 0.0), light_deg=(20.0, 45.0))
    assert _finite(between)
    assert between.min() >= -1e-3 and between.max() <= 1.0 + 1e-3


def test_global_svd_of_a_black_btf_has_rank_zero():
    btf = np.zeros((len(VIEWS), 6, N, N, 3), np.float32)
    model = compress_global_svd(btf, view_dirs_deg=VIEWS, light_dirs_deg=H2[:6], components=4)
    assert model.rank == 0
    out = interpolate(model, view_deg=(10.0, 10.0), light_deg=(10.0, 10.0))
    assert _finite(out) and not out.any()


def test_one_light_fewer_than_components_interpolates():
    btf = _btf(1)
    model = compress_btf(btf, view_dirs_deg=VIEWS, light_dirs_deg=H2[:1], components=8)
    assert np.all(model.rank == 0)  # one image per slot: the mean says everything
    carried = np.cos(np.radians(40.0)) / np.cos(np.radians(H2[0, 0]))  # the light's cosine
    for method in ("nearest", "nearest4"):
        out = interpolate(model, view_deg=VIEWS[3], light_deg=(40.0, 200.0), light_method=method)
        np.testing.assert_allclose(out, btf[3, 0] * carried, atol=2e-3)
    with pytest.raises(BtfError, match="barycentric"):
        interpolate(model, view_deg=VIEWS[3], light_deg=(40.0, 200.0), light_method="barycentric")


def test_duplicated_view_directions_blend_to_their_mean():
    btf = _btf(10)
    views = np.vstack([VIEWS, VIEWS[2:3]])  # view 2 measured twice (two cameras, say)
    twice = np.concatenate([btf, btf[2:3] * 0.5], axis=0)
    model = compress_btf(twice, view_dirs_deg=views, light_dirs_deg=H2[:10], components=9)
    for method in ("nearest4", "barycentric"):
        out = interpolate(model, view_deg=VIEWS[2], light_deg=H2[4], view_method=method)
        assert _finite(out)
        a, b = reconstruct(model, view=2, light=4), reconstruct(model, view=4, light=4)
        # Either copy or a blend of the two, never anything outside them.
        lo, hi = np.minimum(a, b) - 2e-3, np.maximum(a, b) + 2e-3
        assert np.all((out >= lo) & (out <= hi)), method


def test_nan_texels_are_refused_with_the_reason():
    btf = _btf(6)
    btf[0, 2, 3, 3] = np.nan
    with pytest.raises(BtfError, match="NaN"):
        compress_btf(btf, view_dirs_deg=VIEWS, light_dirs_deg=H2[:6], components=2)
    with pytest.raises(BtfError, match="NaN"):
        compress_global_svd(btf, view_dirs_deg=VIEWS, light_dirs_deg=H2[:6], components=2)
