"""Hard cases as properties: every output finite, flags right, no warnings."""

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from processing.photometric import (
    CONDITION_CAP,
    DistantLights,
    NearLights,
    PixelGrid,
    Reason,
    integrate_normals,
    light_set_condition,
    solve,
)
from tests.processing.photometric.ps_synthetic import ring_directions


def assert_well_formed(result, shape):
    assert result.normals.shape == (*shape, 3)
    for name in ("normals", "albedo", "condition", "residual"):
        values = getattr(result, name)
        assert values.dtype == np.float32 and np.all(np.isfinite(values)), name
    assert np.all(result.condition <= CONDITION_CAP)
    assert np.array_equal(result.valid, result.reason == Reason.OK)
    invalid = ~result.valid
    assert np.all(result.normals[invalid] == [0, 0, 1]) and np.all(result.albedo[invalid] == 0)
    assert np.allclose(np.linalg.norm(result.normals, axis=-1), 1.0, atol=1e-6)


def great_circle(n, tilt_deg, spin_deg, eps_deg, rng):
    """n directions on one great circle through the zenith, lifted off it by ≤ eps."""
    angles = np.deg2rad(np.linspace(-70, 70, n))
    spin, tilt = np.deg2rad(spin_deg), np.deg2rad(tilt_deg)
    axis_u = np.array([np.cos(spin), np.sin(spin), 0.0])
    axis_w = np.array([-np.sin(spin) * np.cos(tilt), np.cos(spin) * np.cos(tilt), np.sin(tilt)])
    lift = np.deg2rad(eps_deg) * rng.uniform(-1, 1, n)
    d = (
        np.cos(lift)[:, None]
        * (np.sin(angles)[:, None] * axis_u + np.cos(angles)[:, None] * np.array([0, 0, 1.0]))
        + np.sin(lift)[:, None] * axis_w
    )
    return d / np.linalg.norm(d, axis=1, keepdims=True)


@given(
    n=st.integers(3, 12),
    spin=st.floats(0, 360),
    eps=st.sampled_from([0.0, 1e-9, 1e-4, 0.05, 0.5, 5.0]),
    seed=st.integers(0, 2**16),
)
def test_coplanar_and_nearly_coplanar_lights_are_flagged_by_condition(n, spin, eps, seed):
    rng = np.random.default_rng(seed)
    dirs = great_circle(n, 0.0, spin, eps, rng)
    images = rng.uniform(0.1, 1.0, (n, 4, 5)).astype(np.float32)
    result = solve(images, DistantLights(dirs), method="lsq", max_condition=100.0)
    assert_well_formed(result, (4, 5))
    cond = light_set_condition(DistantLights(dirs).light_matrix())
    if cond > 100.0:
        assert np.all(result.reason == Reason.COPLANAR_LIGHTS)
    else:
        assert not np.any(result.reason == Reason.COPLANAR_LIGHTS)
    if eps == 0.0:
        assert np.all(result.reason == Reason.COPLANAR_LIGHTS)


@given(seed=st.integers(0, 2**16), method=st.sampled_from(["lsq", "threshold", "irls"]))
def test_exactly_three_lights_solve_exactly(seed, method):
    rng = np.random.default_rng(seed)
    theta = np.deg2rad(rng.uniform(20, 60, 3))
    phi = np.deg2rad(rng.uniform(0, 360) + np.array([0, 120, 240]))
    dirs = np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)], 1)
    normal = np.array([0.1, -0.2, 1.0]) / np.linalg.norm([0.1, -0.2, 1.0])
    shading = dirs @ normal
    images = (0.6 * shading)[:, None, None] * np.ones((3, 2, 3))
    result = solve(images, DistantLights(dirs), method=method)
    assert_well_formed(result, (2, 3))
    assert result.valid.all() and np.all(result.lights_used == 3)
    assert np.allclose(result.normals, normal, atol=1e-6)
    assert np.allclose(result.albedo, 0.6, rtol=1e-6)


@given(
    dtype=st.sampled_from([np.uint8, np.uint16, np.float32, np.float64]),
    method=st.sampled_from(["lsq", "threshold", "irls"]),
    colour=st.booleans(),
)
def test_all_dark_pixels_are_flagged_dark(dtype, method, colour):
    dirs = ring_directions(8, theta_deg=(30, 50))
    shape = (8, 3, 4, 3) if colour else (8, 3, 4)
    images = np.zeros(shape, dtype)
    images[:, 0, 0] = 7  # one lit pixel (too few distinct values to solve well, but finite)
    result = solve(images, DistantLights(dirs), method=method)
    assert_well_formed(result, (3, 4))
    assert np.all(result.reason.ravel()[1:] == Reason.DARK)


@given(n_clipped=st.integers(0, 8), method=st.sampled_from(["lsq", "threshold", "irls"]))
def test_saturated_observations_are_dropped_and_flagged(n_clipped, method):
    dirs = ring_directions(8, theta_deg=(30, 50))
    normal = np.array([0.0, 0.0, 1.0])
    images = np.round((dirs @ normal) * 0.5 * 65535)[:, None, None] * np.ones((8, 2, 2))
    images = images.astype(np.uint16)
    images[:n_clipped, 0, 0] = 65535
    result = solve(images, DistantLights(dirs), method=method)
    assert_well_formed(result, (2, 2))
    if 8 - n_clipped < 3:
        assert result.reason[0, 0] == Reason.SATURATED
    else:
        assert result.reason[0, 0] != Reason.SATURATED
        assert result.lights_used[0, 0] <= 8 - n_clipped
    assert result.valid[1, 1] and np.allclose(result.normals[1, 1], normal, atol=1e-4)


@given(
    log_scale=st.floats(-6, 0),
    spread=st.floats(0, 6),
    dtype=st.sampled_from([np.float32, np.float64]),
    seed=st.integers(0, 2**16),
)
def test_float_hdr_with_a_million_to_one_range(log_scale, spread, dtype, seed):
    rng = np.random.default_rng(seed)
    dirs = ring_directions(12, theta_deg=(20, 40))
    normal = np.array([0.2, 0.1, 1.0]) / np.linalg.norm([0.2, 0.1, 1.0])
    albedo = 10.0 ** (log_scale + spread * rng.random((5, 6)))  # up to 10⁶ across pixels
    images = ((dirs @ normal)[:, None, None] * albedo).astype(dtype)
    result = solve(images, DistantLights(dirs))
    assert_well_formed(result, (5, 6))
    assert result.valid.all()
    assert np.allclose(result.normals, normal, atol=1e-4)
    assert np.allclose(result.albedo, albedo, rtol=1e-4)


@given(peak=st.integers(1, 65535), seed=st.integers(0, 2**16))
def test_uint16_full_range(peak, seed):
    rng = np.random.default_rng(seed)
    dirs = ring_directions(9, theta_deg=(20, 45))
    images = rng.integers(0, peak + 1, (9, 4, 4)).astype(np.uint16)
    result = solve(images, DistantLights(dirs))
    assert_well_formed(result, (4, 4))


@given(row=st.integers(0, 5), col=st.integers(0, 6), near=st.booleans())
def test_single_valid_pixel_and_empty_mask(row, col, near):
    dirs = ring_directions(6, theta_deg=(25, 45))
    images = np.full((6, 6, 7), 0.5, np.float32)
    if near:
        lights, extra = NearLights(dirs * 200.0), {"pixels": PixelGrid((6, 7), 0.5)}
    else:
        lights, extra = DistantLights(dirs), {}
    one = np.zeros((6, 7), bool)
    one[row, col] = True
    result = solve(images, lights, mask=one, **extra)
    assert_well_formed(result, (6, 7))
    assert result.reason[row, col] != Reason.MASKED
    assert np.sum(result.reason == Reason.MASKED) == 41
    height = integrate_normals(result.normals, pitch_mm=0.5, mask=one)
    assert height.height_mm[row, col] == 0 and np.all(np.isfinite(height.height_mm))
    empty = solve(images, lights, mask=np.zeros((6, 7), bool), **extra)
    assert_well_formed(empty, (6, 7))
    assert np.all(empty.reason == Reason.MASKED)
    flat = integrate_normals(empty.normals, pitch_mm=0.5, mask=np.zeros((6, 7), bool))
    assert not flat.valid.any() and np.all(flat.height_mm == 0)
