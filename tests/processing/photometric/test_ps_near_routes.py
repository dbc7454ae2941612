"""Near lamps: the compiled per-pixel route gives the numpy route's answer.

With a light vector per pixel, the IRLS reweighting, the sums of the fit and
the conditions run compiled (``_irls_kernel``, ``_near_kernel``). The
reference here takes the same steps in numpy (``ps_numpy_route``): the IRLS
steps with a sort per pixel, the per-pixel normal matrices, moments and
energies as einsums, the conditions from batched eigenvalues, the fit by
``_block._fit``.
"""

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from processing.photometric import NearLights, Reason, _block, _system
from processing.photometric._block import _fit, _weights, solve_block
from processing.photometric._inputs import check_stack
from processing.photometric._kernels import sum_arrays
from processing.photometric._near_kernel import near_weighted_sums
from processing.photometric._robust import reference_level
from processing.photometric._solve import _check_options, _read_chunk
from tests.processing.photometric.ps_numpy_route import (
    condition,
    irls_weights_stepwise,
    near_light_vectors,
    normal_matrix,
)
from tests.processing.photometric.ps_synthetic import ring_directions

N_LIGHTS = 16
LAMP_HEIGHT_MM = 40.0


def lamp_positions(distance_mm):
    """A ring of lamps, all at one height, ``distance_mm`` out from the axis."""
    dirs = ring_directions(N_LIGHTS, theta_deg=(30, 50, 70))
    xy = dirs[:, :2] / np.linalg.norm(dirs[:, :2], axis=1, keepdims=True)
    radius = distance_mm * np.linspace(0.6, 1.0, N_LIGHTS)[:, None]
    return np.column_stack([xy * radius, np.full(N_LIGHTS, LAMP_HEIGHT_MM)])


def near_scene(distance_mm, dtype, colour, seed=0):
    """Chunk, per-pixel lights (L, n, 3) and options of 1100 pixels (more than a tile).

    Dark, shadowed, glossy, facing-away and clipped pixels; a few pixels at the
    lamps' height (coplanar light vectors) or just below it (ill-conditioned).
    """
    rng = np.random.default_rng(seed)
    n = 1100
    points = np.column_stack([rng.uniform(-10, 10, (n, 2)), np.zeros(n)])
    points[30:33, 2] = LAMP_HEIGHT_MM  # every lamp in the pixel's plane
    points[33:36, 2] = LAMP_HEIGHT_MM - 0.05
    lights = NearLights(lamp_positions(distance_mm)).light_vectors(points)
    normals = rng.normal([0.0, 0.0, 1.0], 0.3, (n, 3))
    normals[:5] = [0.3, 0.1, -0.95]  # facing away
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    shading = np.einsum("lni,ni->ln", lights, normals)
    shading[:, 5:] = np.clip(shading[:, 5:], 0, None)  # attached shadows
    shading[rng.random(shading.shape) < 0.1] *= 0.05  # cast shadows
    shading[rng.random(shading.shape) < 0.05] += 0.8  # highlights
    images = shading * rng.uniform(0.2, 0.6, n) / shading.max()
    if colour:
        images = images[..., None] * np.array([1.0, 0.8, 0.6])
    images = images + rng.normal(0, 0.004, images.shape)
    images[:, 10:13] = 0.0  # dark pixels
    if np.issubdtype(dtype, np.integer):
        top = np.iinfo(dtype).max
        images = np.round(np.clip(images, 0, 1) * top)
        images[:4, 20] = top  # 4 observations clipped
        images[:14, 21] = top  # 14 clipped: too few lamps left
    images = images.astype(dtype).reshape((N_LIGHTS, 1, n) + ((3,) if colour else ()))
    stack = check_stack(images, N_LIGHTS, None)
    return _read_chunk(stack, slice(0, n), 0.01), lights


def numpy_near_sums(obs, grey, usable, all_usable, lights, options):
    """:func:`_block._near_sums` in numpy: the numpy IRLS steps, einsums, batched eigenvalues."""
    n = grey.shape[1]
    a_full = normal_matrix(lights, np.ones(grey.shape))
    if options.method == "irls":
        weights = irls_weights_stepwise(
            grey,
            usable,
            lights,
            shadow_fraction=options.shadow_fraction,
            highlight_fraction=options.highlight_fraction,
            iterations=options.irls_iterations,
            max_condition=options.max_condition,
        )
    else:
        weights = _weights(grey, usable, lights, all_usable, options)
    w = np.ones(grey.shape) if weights is None else weights.astype(np.float64)
    a = normal_matrix(lights, w)
    g = _system.moment(lights, w, obs)
    wobs = obs * (w[..., None] if obs.ndim == 3 else w)
    e = np.einsum("ln...,ln...->n...", wobs, obs)
    upper = a.reshape(n, 9)[:, [0, 1, 2, 4, 5, 8]].T
    moment = g[..., None] if g.ndim == 2 else g
    energy = e[:, None] if e.ndim == 1 else e
    sums = (upper, moment.transpose(2, 1, 0), energy.T, w.sum(axis=0), np.count_nonzero(w, 0))
    return condition(a_full), tuple(np.ascontiguousarray(s, float) for s in sums)


def _floor_ties(obs, options):
    """Pixels with an observation whose support differs in float32 and float64."""
    grey = obs.mean(axis=2) if obs.ndim == 3 else obs
    floor = options.shadow_fraction * reference_level(grey, options.highlight_fraction)
    floor32 = options.shadow_fraction * reference_level(
        grey.astype(np.float32), options.highlight_fraction
    ).astype(np.float64)
    return ((grey >= floor) != (grey.astype(np.float32) >= floor32)).any(axis=0)


@pytest.mark.parametrize("n_lights", [3, 5, 9])
@pytest.mark.parametrize("channels", [0, 1, 3])
def test_near_weighted_sums_match_the_einsums(n_lights, channels):
    rng = np.random.default_rng(n_lights + channels)
    n = 1100
    weights = rng.random((n_lights, n)).astype(np.float32)
    weights[rng.random(weights.shape) < 0.3] = 0
    planes = rng.random((channels, n_lights, n))
    lights = rng.normal(0, 1, (n_lights, n, 3))
    sums = sum_arrays(n, channels)
    near_weighted_sums(weights, planes, np.ascontiguousarray(np.moveaxis(lights, 2, 0)), *sums)
    w = weights.astype(np.float64)
    a = normal_matrix(lights, w)
    assert_allclose(sums[0], a.reshape(n, 9)[:, [0, 1, 2, 4, 5, 8]].T, rtol=1e-12, atol=1e-12)
    assert_allclose(sums[1], np.einsum("lni,ln,cln->cin", lights, w, planes), rtol=1e-12,
                    atol=1e-12)  # fmt: skip
    assert_allclose(sums[2], np.einsum("ln,cln->cn", w, planes**2), rtol=1e-12, atol=1e-12)
    assert_allclose(sums[3], w.sum(axis=0), rtol=1e-12)
    assert_array_equal(sums[4], np.count_nonzero(weights, axis=0))


@pytest.mark.parametrize("distance_mm", [15.0, 60.0, 1000.0])
@pytest.mark.parametrize(("dtype", "colour"), [(np.float64, False), (np.uint8, True)])
@pytest.mark.parametrize("method", ["lsq", "threshold", "irls"])
def test_compiled_near_route_matches_the_numpy_route(
    distance_mm, dtype, colour, method, monkeypatch
):
    chunk, lights = near_scene(distance_mm, dtype, colour)
    options = _check_options(method, 0.01, 100.0, 0.05, 0.1, 3)
    compiled = solve_block(*chunk, lights, None, options)
    monkeypatch.setattr(_block, "_near_sums", numpy_near_sums)
    reference = solve_block(*chunk, lights, None, options)
    if method == "irls":
        # The compiled reweighting compares its float32 copy of the observations
        # with the shadow floor (5 % of the reference level), the numpy steps the
        # float64 values: where 8-bit levels sit exactly on the floor the two
        # support decisions differ and the iterations part. Those pixels aside.
        ties = _floor_ties(chunk[0], options)
        assert ties.mean() < 0.05
        compiled = {key: value[~ties] for key, value in compiled.items()}
        reference = {key: value[~ties] for key, value in reference.items()}
    assert_array_equal(compiled["reason"], reference["reason"])
    reasons = set(compiled["reason"].tolist())
    assert {Reason.OK, Reason.DARK, Reason.COPLANAR_LIGHTS} <= reasons
    if dtype == np.uint8:
        assert Reason.SATURATED in reasons
    # lsq, threshold: the same weights, float64 sums in another order. irls: float32
    # reweighting with sums in another order, weights equal to ~3e-4 (normals seen
    # to ~1e-4), the same tolerances as distant lamps against the numpy steps.
    normal, albedo, cond, residual = (
        (1e-3, 1e-3, 1e-3, (1e-2, 1e-5)) if method == "irls" else (1e-9, 1e-9, 1e-6, (1e-6, 1e-9))
    )
    # Exactly coplanar light vectors: a condition from rounding noise, > 1e6 both ways;
    # otherwise the smallest eigenvalue is good to ~eps·λmax: rtol ~eps·cond² (1e-8 at 1e4).
    singular = reference["condition"] > 1e6
    agree = (
        (compiled["reason"] == reference["reason"])
        & (compiled["lights_used"] == reference["lights_used"])
        & _close(compiled["normals"], reference["normals"], 0.0, normal)
        & _close(compiled["albedo"], reference["albedo"], albedo, 1e-8)
        & np.where(
            singular,
            compiled["condition"] > 1e6,
            _close(compiled["condition"], reference["condition"], cond, 0.0),
        )
        # a residual near 0 is the root of a cancelling difference of sums
        & _close(compiled["residual"], reference["residual"], *residual)
    )
    # irls: an observation's weight near a cut (the biweight's edge, the attached
    # shadow test) may fall the other way in float32 and part the iterations (8-bit
    # levels tie often).
    assert (~agree).mean() <= (0.01 if method == "irls" else 0.0)  # irls: 0.65 % seen


def _close(actual, desired, rtol, atol):
    """Per pixel: every value within ``atol + rtol·|desired|`` (over channels or axes)."""
    ok = np.abs(actual - desired) <= atol + rtol * np.abs(desired)
    return ok.reshape(len(ok), -1).all(axis=1)


@pytest.mark.parametrize("distance_mm", [15.0, 60.0, 1000.0])
def test_compiled_light_vectors_match_the_numpy_formula(distance_mm):
    rng = np.random.default_rng(1)
    points = np.column_stack([rng.uniform(-10, 10, (500, 2)), rng.uniform(-2, 2, 500)])
    positions = lamp_positions(distance_mm)
    intensities = rng.uniform(0.5, 2.0, N_LIGHTS)
    lights = NearLights(positions, intensities).light_vectors(points)
    assert lights.shape == (N_LIGHTS, 500, 3)
    # the x, y, z planes the compiled route reads, without a copy
    assert np.moveaxis(lights, 2, 0).flags.c_contiguous
    assert_allclose(lights, near_light_vectors(positions, intensities, points), rtol=1e-13)


def test_numpy_fit_is_the_reference_fit():
    # The reference's fit is _fit from the numpy sums; the compiled route takes
    # fit_from_sums, held to _fit in test_ps_routes. Here: one scene end to end.
    chunk, lights = near_scene(60.0, np.float64, False)
    obs, energy = chunk[0], chunk[1]
    options = _check_options("lsq", 0.01, 100.0, 0.05, 0.1, 3)
    a = normal_matrix(lights, np.ones(obs.shape))
    cond = condition(a)
    g = _system.moment(lights, None, obs)
    used = np.full(obs.shape[1], N_LIGHTS)
    normals, *_ = _fit(a, g, energy, used.astype(float), used, cond, 100.0)
    compiled = solve_block(*chunk, lights, None, options)
    ok = compiled["reason"] == Reason.OK
    assert ok.mean() > 0.5
    assert_allclose(compiled["normals"][ok], normals[ok], atol=1e-9)
