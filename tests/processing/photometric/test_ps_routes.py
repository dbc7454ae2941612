"""The pseudo-inverse route and the per-pixel route give the same answer.

``solve(method="lsq")`` with distant lamps answers pixels whose observations
are all usable with one product by the pseudo-inverse and sends the rest
(saturated observations, bad values) to the per-pixel float64 route. The
reference here runs the per-pixel route on every pixel.
"""

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from processing.photometric import DistantLights, PhotometricError, Reason, solve
from processing.photometric._block import _fit, _fit_compiled, solve_block
from processing.photometric._inputs import check_stack
from processing.photometric._irls_kernel import (
    _ABSENT,
    _float_keys,
    _select,
    _within_condition,
)
from processing.photometric._kernels import condition3, conditions, sum_arrays, weighted_sums
from processing.photometric._result import CONDITION_CAP
from processing.photometric._robust import irls_weights
from processing.photometric._solve import _check_options, _read_chunk
from tests.processing.photometric.ps_numpy_route import (
    FULL_FROM_PAIRS,
    condition,
    irls_weights_stepwise,
    median,
)
from tests.processing.photometric.ps_synthetic import ring_directions

DIRS = ring_directions(16, theta_deg=(20, 45, 65))
N_PIXELS = 60


def per_pixel_reference(images, dirs, *, dark_level=0.0):
    """Every pixel through the per-pixel route, float64 throughout."""
    stack = check_stack(images, len(dirs), None)
    options = _check_options("lsq", dark_level, 100.0, 0.05, 0.1, 3)
    chunk = _read_chunk(stack, slice(0, stack.values.shape[1]), dark_level)
    return solve_block(*chunk, dirs, np.linalg.cond(dirs), options)


def scene(dtype, colour, *, exclusions, seed=0):
    """(L, 6, 10[, 3]) images; with exclusions: dark, shadowed, glossy, tilted-away pixels."""
    rng = np.random.default_rng(seed)
    normals = rng.normal([0.0, 0.0, 1.0], 0.3, (N_PIXELS, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    albedo = rng.uniform(0.2, 0.6, N_PIXELS)
    shading = DIRS @ normals.T
    if exclusions:
        normals[:5] = [0.3, 0.1, -0.95]  # facing away: n_z < 0 (negative float images)
        shading = DIRS @ normals.T
        shading[:, 5:] = np.clip(shading[:, 5:], 0, None)  # attached shadows
        shading[rng.random(shading.shape) < 0.1] *= 0.05  # cast shadows
        shading[rng.random(shading.shape) < 0.05] += 0.8  # highlights
    images = shading * albedo
    if colour:
        images = images[..., None] * np.array([1.0, 0.8, 0.6])
    images = images + rng.normal(0, 0.004, images.shape)
    if exclusions:
        images[:, 10:13] = 0.0  # dark pixels
    if np.issubdtype(dtype, np.integer):
        top = np.iinfo(dtype).max
        images = np.round(np.clip(images, 0, 1) * top)
        if exclusions:
            images[:4, 20] = top  # saturated: 4 observations clipped
            images[:14, 21] = top  # 14 clipped: fewer than 3 left
    shape = (len(DIRS), 6, 10) + ((3,) if colour else ())
    return images.astype(dtype).reshape(shape)


@pytest.mark.parametrize("dtype", [np.float32, np.float64, np.uint8, np.uint16])
@pytest.mark.parametrize("colour", [False, True])
@pytest.mark.parametrize("exclusions", [False, True])
def test_routes_agree(dtype, colour, exclusions):
    images = scene(dtype, colour, exclusions=exclusions)
    result = solve(images, DistantLights(DIRS), method="lsq", dark_level=0.01, chunk_pixels=16)
    reference = per_pixel_reference(images, DIRS, dark_level=0.01)
    albedo_shape = (N_PIXELS, 3) if colour else (N_PIXELS,)
    assert_array_equal(result.reason.ravel(), reference["reason"])
    assert_array_equal(result.lights_used.ravel(), reference["lights_used"])
    assert_allclose(result.condition.ravel(), reference["condition"], rtol=1e-6)
    assert_allclose(result.normals.reshape(-1, 3), reference["normals"], atol=2e-6)
    assert_allclose(result.albedo.reshape(albedo_shape), reference["albedo"], rtol=2e-6, atol=1e-7)
    assert_allclose(result.residual.ravel(), reference["residual"], rtol=1e-4, atol=1e-7)
    if exclusions:
        reasons = set(np.unique(result.reason).tolist())
        assert {Reason.OK, Reason.DARK} <= reasons
        if np.issubdtype(dtype, np.integer):
            assert result.reason.ravel()[21] == Reason.SATURATED
            assert result.lights_used.ravel()[20] == len(DIRS) - 4
        else:
            assert Reason.BELOW_HORIZON in reasons


def test_mask_packs_the_chosen_pixels_and_leaves_the_rest():
    images = scene(np.float32, False, exclusions=True)
    mask = np.random.default_rng(1).random((6, 10)) < 0.3
    masked = solve(images, DistantLights(DIRS), method="lsq", mask=mask, chunk_pixels=4)
    whole = solve(images, DistantLights(DIRS), method="lsq")
    assert np.all(masked.reason[~mask] == Reason.MASKED)
    for name in ("reason", "lights_used"):
        assert_array_equal(getattr(masked, name)[mask], getattr(whole, name)[mask], name)
    for name in ("normals", "albedo", "condition", "residual"):
        # float32 sums may round differently in a packed chunk than in a strided one
        assert_allclose(getattr(masked, name)[mask], getattr(whole, name)[mask], atol=1e-6)


def test_a_float32_stack_overflowing_its_squares_is_solved_in_float64():
    # 1e20² overflows float32: the pixel goes to the float64 route and is solved there.
    images = scene(np.float64, False, exclusions=False) * 1e20
    result = solve(images.astype(np.float32), DistantLights(DIRS), method="lsq")
    reference = per_pixel_reference(images.astype(np.float32), DIRS)
    assert result.valid.all()
    assert_allclose(result.residual.ravel(), reference["residual"], rtol=1e-4)


def test_a_nan_is_reported_at_its_pixel_by_either_route():
    images = scene(np.float32, False, exclusions=False)
    images[3, 4, 7] = np.nan
    with pytest.raises(PhotometricError, match=r"images\[3\].*row 4, column 7"):
        solve(images, DistantLights(DIRS), method="lsq")


@pytest.mark.parametrize("n_lights", [7, 8])
def test_irls_scale_is_the_median_of_the_supported_residuals(n_lights):
    rng = np.random.default_rng(n_lights)
    residual = rng.normal(0, 1, (n_lights, 40))
    support = rng.random((n_lights, 40)) < 0.6
    support[:, 0] = False
    support[:, 1] = np.arange(n_lights) == 2
    expected = [
        np.median(np.abs(residual[support[:, j], j])) if support[:, j].any() else 0.0
        for j in range(40)
    ]
    assert_allclose(median(np.abs(residual), support), expected, rtol=1e-6)


def _irls_both_ways(grey, usable):
    """IRLS weights with the lamps given once (compiled) and per pixel (the numpy steps)."""
    options = {
        "shadow_fraction": 0.05,
        "highlight_fraction": 0.1,
        "iterations": 3,
        "max_condition": 100.0,
    }
    per_pixel = np.broadcast_to(DIRS[:, None, :], (*grey.shape, 3))
    return (
        irls_weights(grey, usable, DIRS, **options),
        irls_weights_stepwise(grey, usable, per_pixel, **options),
    )


def test_compiled_irls_weights_match_the_per_pixel_light_steps():
    # Distant lamps reweight compiled; the same lamps given per pixel (as near
    # lamps are) through the numpy steps must give the same weights.
    images = scene(np.float64, False, exclusions=True)
    grey = images.reshape(len(DIRS), -1)
    usable = np.random.default_rng(3).random(grey.shape) > 0.05
    compiled, stepwise = _irls_both_ways(grey, usable)
    assert compiled.dtype == np.float32 and compiled.shape == grey.shape
    # float32 sums over the lights in another order: weights agree to ~1e-4
    assert_allclose(compiled, stepwise, atol=5e-4)
    assert 0 < (compiled == 0).mean() < 0.5  # shadows, highlights and clipped observations out


def test_compiled_irls_weights_match_the_numpy_steps_on_tied_values():
    # Observations on a few levels tie many times over (the reference level, a
    # flat pixel's residuals): the compiled order statistics must stay exact.
    images = scene(np.float64, False, exclusions=True, seed=4)
    grey = np.round(images.reshape(len(DIRS), -1) * 6) / 6
    grey[:, 20:23] = 0.5  # one value under every lamp
    usable = np.ones(grey.shape, bool)
    compiled, stepwise = _irls_both_ways(grey, usable)
    assert_allclose(compiled, stepwise, atol=5e-4)


@pytest.mark.parametrize("levels", [3, 50, 2**20])
@pytest.mark.parametrize("n_keys", [40, 43])  # lights counted four at a time, and the rest
def test_compiled_selection_is_exact_with_ties_signs_and_absent_keys(levels, n_keys):
    # The reweighting's order statistics: rank (count − 1) // 2 and the next one,
    # absent keys sorting last. Few levels tie many keys at the answer.
    rng = np.random.default_rng(levels)
    m = 64
    values = (rng.integers(-levels, levels, (n_keys, m)) / levels).astype(np.float32)
    keys = np.empty(values.shape, np.int32)
    for row, out in zip(values, keys, strict=True):
        _float_keys(row, out)
    absent = rng.random(keys.shape) < 0.3
    absent[:, 0] = True  # nothing present: both answers are absent keys
    absent[:, 1] = np.arange(n_keys) != 5  # one present key
    keys[absent] = _ABSENT
    count = (~absent).sum(axis=0)
    order = np.maximum((count - 1) // 2, 0).astype(np.int32)
    lower, upper = np.empty(m, np.int32), np.empty(m, np.int32)
    _select(keys, m, order, lower, upper)
    ordered = np.sort(keys, axis=0)
    assert_array_equal(lower, ordered[order, np.arange(m)])
    assert_array_equal(upper, ordered[order + 1, np.arange(m)])


def test_condition_certificate_decides_as_the_eigenvalues_do():
    # The reweighting's fits skip the eigenvalues where tr³ / (4 det) bounds the
    # condition; the decision must be the one the eigenvalues give, for spread,
    # nearly coplanar and exactly coplanar lamp sets and every weighting.
    rng = np.random.default_rng(5)
    for spread in (1.0, 0.3, 0.05, 0.01, 0.0):
        dirs = rng.normal(0, 1, (12, 3)) * [1.0, 1.0, spread] + [0.0, 0.0, 1.0]
        for _ in range(40):
            weights = rng.random(12) * (rng.random(12) < 0.7)
            a = (dirs * weights[:, None]).T @ dirs
            pairs = a[0, 0], a[0, 1], a[0, 2], a[1, 1], a[1, 2], a[2, 2]
            det = np.linalg.det(a)
            for limit in (1.5, 10.0, 100.0, 1e4):
                expected = condition3(*pairs) <= limit
                assert _within_condition(*pairs, det, limit) == expected


@pytest.mark.parametrize("n_lights", [3, 7, 8])  # lights four at a time, the rest, or both
@pytest.mark.parametrize("weight_dtype", [np.float32, np.float64])
def test_compiled_weighted_sums_match_the_sums_over_the_lights(n_lights, weight_dtype):
    rng = np.random.default_rng(n_lights)
    n, channels = 1100, 3  # more pixels than one tile
    weights = rng.random((n_lights, n)).astype(weight_dtype)
    weights[rng.random(weights.shape) < 0.3] = 0  # rejected observations
    planes = rng.random((channels, n_lights, n))
    lights = ring_directions(n_lights, theta_deg=(30, 60))
    upper, moment = np.empty((6, n)), np.empty((channels, 3, n))
    energy, weight_sum, used = np.empty((channels, n)), np.empty(n), np.empty(n)
    weighted_sums(weights, planes, lights, upper, moment, energy, weight_sum, used)
    w = weights.astype(np.float64)
    pairs = [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)]
    assert_allclose(
        upper, [(lights[:, i] * lights[:, j]) @ w for i, j in pairs], rtol=1e-12, atol=1e-14
    )
    assert_allclose(moment, np.einsum("li,ln,cln->cin", lights, w, planes), rtol=1e-12, atol=1e-14)
    assert_allclose(energy, np.einsum("ln,cln->cn", w, planes**2), rtol=1e-12, atol=1e-14)
    assert_allclose(weight_sum, w.sum(axis=0), rtol=1e-12, atol=1e-14)
    assert_array_equal(used, np.count_nonzero(weights, axis=0))


@pytest.mark.parametrize("dtype", [np.float32, np.uint8])
@pytest.mark.parametrize("colour", [False, True])
def test_irls_in_one_compiled_pass_matches_the_per_pixel_light_steps(dtype, colour):
    # The reweighting and the final fit's sums are one compiled pass, with one
    # light matrix or (the same lamps) a light vector per pixel, as near lamps
    # are given. Dark, clipped, shadowed, glossy and facing-away pixels included.
    images = scene(dtype, colour, exclusions=True)
    stack = check_stack(images, len(DIRS), None)
    options = _check_options("irls", 0.01, 100.0, 0.05, 0.1, 3)
    chunk = _read_chunk(stack, slice(0, N_PIXELS), 0.01)
    one_pass = solve_block(*chunk, DIRS, np.linalg.cond(DIRS), options)
    per_pixel = np.broadcast_to(DIRS[:, None, :], (len(DIRS), N_PIXELS, 3))
    stepwise = solve_block(*chunk, per_pixel, None, options)
    assert_array_equal(one_pass["reason"], stepwise["reason"])
    hard = {Reason.OK, Reason.DARK} | ({Reason.SATURATED} if dtype == np.uint8 else set())
    assert hard <= set(one_pass["reason"].tolist())
    assert_array_equal(one_pass["lights_used"], stepwise["lights_used"])
    # weights agree to ~1e-4 (float32 sums over the lights in another order)
    assert_allclose(one_pass["normals"], stepwise["normals"], atol=1e-3)
    assert_allclose(one_pass["albedo"], stepwise["albedo"], rtol=1e-3, atol=1e-6)
    assert_allclose(one_pass["condition"], stepwise["condition"], rtol=1e-3)


def test_compiled_conditions_match_the_batched_eigenvalues():
    # The weighted solvers' conditions come compiled from the sums' upper
    # triangles; they must be the numpy route's, down to singular and zero systems.
    rng = np.random.default_rng(6)
    tilt = np.deg2rad(np.linspace(-60, 60, 12))
    in_plane = np.stack([np.sin(tilt), np.zeros(12), np.cos(tilt)], axis=1)  # y = 0
    dirs = np.concatenate([ring_directions(12), in_plane])
    weights = rng.random((24, 300)) * (rng.random((24, 300)) < 0.5)
    weights[:12, :100] = 0  # the lamps of one plane only: coplanar
    weights[:, 100] = 0  # nothing used
    a = np.einsum("li,lj,ln->nij", dirs, dirs, weights)
    upper = a.reshape(-1, 9)[:, [0, 1, 2, 4, 5, 8]].T.copy()
    out = np.empty(300)
    conditions(upper, out)
    expected = condition(a)
    # Singular systems: both give rounding noise far above any limit, or the cap.
    assert (out[:100] > 1e6).all() and (expected[:100] > 1e6).all()
    assert out[100] == expected[100] == CONDITION_CAP
    assert_allclose(out[101:], expected[101:], rtol=1e-9)


@pytest.mark.parametrize("channels", [1, 3])
def test_compiled_fit_from_sums_matches_the_numpy_fit(channels):
    # The weighted solvers with one light matrix solve from their compiled sums,
    # compiled; the numpy fit from the same sums must agree, down to pixels with
    # too few lamps, coplanar lamps, and nothing lit.
    rng = np.random.default_rng(channels)
    n_lights, n = 24, 400
    dirs = ring_directions(n_lights)
    weights = rng.random((n_lights, n)) * (rng.random((n_lights, n)) < 0.6)
    weights[2:, :20] = 0  # two lamps: too few
    weights[:, 20:40] = 0  # none
    weights[n_lights // 3 :, 40:60] = 0  # one ring: nearly coplanar for a strict limit
    planes = rng.random((channels, n_lights, n)) * 0.8
    planes[:, :, 60:80] = 0  # dark: x = 0
    sums = sum_arrays(n, channels)
    weighted_sums(weights, planes, dirs, *sums)
    upper, moment, energy, weight_sum, used = sums
    condition = np.empty(n)
    conditions(upper, condition)
    a = upper.T[:, FULL_FROM_PAIRS].reshape(-1, 3, 3)
    g = moment.transpose(2, 1, 0) if channels > 1 else moment[0].T
    e = energy.T if channels > 1 else energy[0]
    for limit in (100.0, 3.0):
        compiled = _fit_compiled(sums, condition, limit)
        reference = _fit(a, g, e, weight_sum, used.astype(np.int64), condition, limit)
        assert_array_equal(compiled[3], reference[3])  # solved with ρ > 0
        assert 0 < compiled[3].sum() < n - 60
        for got, expected in zip(compiled[:3], reference[:3], strict=True):
            assert_allclose(got, expected, rtol=1e-10, atol=1e-12)
