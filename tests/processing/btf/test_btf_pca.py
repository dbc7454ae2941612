"""Per-view PCA, the global SVD and their hard cases, on data with a known rank."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from processing.btf import (
    BtfError,
    compress_btf,
    compress_global_svd,
    compress_view,
    compress_view_svd,
    reconstruct,
    rmse,
)
from processing.btf.synthetic import SyntheticBTF
from rig.geometry import Sampling

N = 16


def _low_rank_stack(n_lights: int, rank: int, seed: int = 0) -> np.ndarray:
    """mean + rank random components: a stack whose centred rank is exactly ``rank``."""
    rng = np.random.default_rng(seed)
    mean = rng.random((N, N, 3))
    basis = rng.normal(size=(rank, N, N, 3))
    weights = rng.normal(size=(n_lights, rank))
    return (mean + np.einsum("lk,kyxc->lyxc", weights, basis)).astype(np.float32)


def _recon(slot) -> np.ndarray:
    return slot.mean.astype(np.float64) + np.einsum(
        "lk,kyxc->lyxc", slot.weights.astype(np.float64), slot.basis.astype(np.float64)
    )


def test_exact_reconstruction_when_components_reach_the_rank():
    stack = _low_rank_stack(20, rank=5)
    slot = compress_view(stack, components=5, storage=np.float32)
    assert slot.rank == 5
    np.testing.assert_allclose(_recon(slot), stack, atol=2e-5 * np.abs(stack).max())
    assert slot.singular_values[5] < 1e-5 * slot.singular_values[0]


def test_the_gram_route_matches_numpy_svd():
    stack = np.asarray(SyntheticBTF(N, [[30.0, 40.0]], Sampling.named("H2").directions))[0]
    for c in (1, 4, 16):
        fast = compress_view(stack, components=c, storage=np.float32)
        slow = compress_view_svd(stack, components=c, storage=np.float32)
        assert rmse(_recon(fast), stack) == pytest.approx(rmse(_recon(slow), stack), rel=1e-4)
        np.testing.assert_allclose(
            fast.singular_values,
            slow.singular_values,
            rtol=1e-4,
            atol=1e-6 * slow.singular_values[0],
        )
        # Same subspace, same sign convention, same scaling.
        np.testing.assert_allclose(fast.basis, slow.basis, atol=1e-3)


def test_error_decreases_with_components():
    stack = np.asarray(SyntheticBTF(N, [[45.0, 100.0]], Sampling.named("H2").directions))[0]
    errors = [rmse(_recon(compress_view(stack, components=c)), stack) for c in (1, 2, 4, 8, 16)]
    assert np.all(np.diff(errors) < 0)
    assert errors[-1] < 0.1 * errors[0]


def test_constant_view_has_rank_zero():
    stack = np.full((9, N, N, 3), 0.25, np.float32)
    slot = compress_view(stack, components=4)
    assert slot.rank == 0
    assert not slot.basis.any()
    assert not slot.weights.any()
    np.testing.assert_array_equal(slot.mean, np.float16(0.25))
    assert np.all(np.isfinite(slot.singular_values))


def test_fewer_lights_than_components():
    stack = _low_rank_stack(3, rank=3)
    slot = compress_view(stack, components=8, storage=np.float32)
    assert slot.basis.shape == (8, N, N, 3)
    assert slot.weights.shape == (3, 8)
    assert slot.rank == 2  # three images span a 2-D affine subspace
    np.testing.assert_allclose(_recon(slot), stack, atol=1e-4)
    assert not slot.basis[2:].any()


def test_duplicated_lights_reduce_the_rank_not_the_accuracy():
    stack = _low_rank_stack(6, rank=5)
    doubled = np.concatenate([stack, stack[:3]])
    slot = compress_view(doubled, components=9, storage=np.float32)
    assert slot.rank == 5
    np.testing.assert_allclose(_recon(slot), doubled, atol=2e-4)


def test_dtype_policy():
    stack16 = (np.random.default_rng(1).random((5, N, N, 3)) * 4000).astype(np.uint16)
    for stack in (stack16, stack16.astype(np.float64), stack16.astype(np.float32)):
        slot = compress_view(stack, components=3)
        assert slot.mean.dtype == np.float16
        assert slot.basis.dtype == np.float16
        assert slot.weights.dtype == np.float32
        assert slot.singular_values.dtype == np.float32
        assert np.abs(slot.basis).max() == pytest.approx(1.0, abs=1e-3)
    assert compress_view(stack16, components=3, storage=np.float32).basis.dtype == np.float32


@pytest.mark.parametrize(
    ("stack", "components", "match"),
    [
        (np.zeros((4, N, N, 2)), 2, "view stack"),
        (np.zeros((4, N, 0, 3)), 2, "view stack"),
        (np.full((4, N, N, 3), np.nan), 2, "NaN"),
        (np.zeros((4, N, N, 3)), 0, "components"),
        (np.full((4, N, N, 3), 1e6), 2, "float16"),
    ],
)
def test_bad_input_is_named(stack, components, match):
    with pytest.raises(BtfError, match=match):
        compress_view(stack, components=components)


def test_global_svd_recovers_a_low_rank_btf():
    rng = np.random.default_rng(3)
    eigen = rng.random((3, 5, N, N, 3))
    w = rng.normal(size=(7, 3))
    btf = np.einsum("vk,klyxc->vlyxc", w, eigen).astype(np.float32)
    views = [[t, p] for t, p in zip(np.linspace(0, 75, 7), np.linspace(0, 300, 7), strict=True)]
    lights = Sampling.named("H2").directions[:5]
    model = compress_global_svd(
        btf, view_dirs_deg=views, light_dirs_deg=lights, components=4, storage=np.float32
    )
    assert model.rank == 3
    for v in range(7):
        for li in range(5):
            np.testing.assert_allclose(reconstruct(model, view=v, light=li), btf[v, li], atol=1e-4)


def test_compress_btf_streams_views_and_checks_tables():
    dirs = Sampling.named("H2").directions[:9]
    source = SyntheticBTF(N, dirs, dirs)
    model = compress_btf(source, view_dirs_deg=dirs, light_dirs_deg=dirs, components=8)
    reference = np.asarray(source)
    assert model.mean.shape == (9, N, N, 3)
    assert model.basis.shape == (9, 8, N, N, 3)
    assert model.weights.shape == (9, 9, 8)
    assert rmse(reconstruct(model, view=4, light=7), reference[4, 7]) < 0.01
    with pytest.raises(BtfError, match="light_dirs_deg"):
        compress_btf(source, view_dirs_deg=dirs, light_dirs_deg=dirs[:5], components=2)
    with pytest.raises(BtfError, match="btf"):
        compress_btf(np.zeros((2, 3, 4)), view_dirs_deg=dirs, light_dirs_deg=dirs, components=2)


@given(
    n_lights=st.integers(1, 12),
    rank=st.integers(0, 6),
    components=st.integers(1, 10),
    scale=st.sampled_from([0.0, 1e-6, 1.0, 1e3]),
    duplicate=st.booleans(),
    seed=st.integers(0, 1000),
)
def test_any_stack_gives_finite_bounded_results(n_lights, rank, components, scale, duplicate, seed):
    stack = _low_rank_stack(n_lights, rank=min(rank, n_lights), seed=seed)[:, :4, :4] * scale
    if duplicate:
        stack = np.concatenate([stack, stack])
    slot = compress_view(stack, components=components, storage=np.float32)
    for value in (slot.mean, slot.basis, slot.weights, slot.singular_values):
        assert np.all(np.isfinite(value))
    assert 0 <= slot.rank <= min(components, len(stack) - 1, rank if scale else 0)
    # Never worse than the mean alone.
    assert rmse(_recon(slot), stack) <= rmse(slot.mean[None], stack) * (1 + 1e-5) + 1e-9
