"""Accuracy, flags and input checks of photometric-stereo solves on synthetic images."""

import numpy as np
import pytest
from numpy.testing import assert_allclose

from processing.photometric import (
    DistantLights,
    NearLights,
    PhotometricError,
    PixelGrid,
    Reason,
    solve,
)
from rig.errors import RigError
from tests.processing.photometric.ps_synthetic import (
    Surface,
    angular_error_deg,
    bumps,
    render_distant,
    render_near,
    ring_directions,
    specular,
)


@pytest.fixture(scope="module")
def surface():
    return bumps(64, seed=4)


def gentle(surface):
    """Tilts of at most ~37°, lights at θ ≤ 40°: no attached shadows anywhere."""
    return surface


def test_distant_lambertian_noise_free_below_005_deg(surface):
    dirs = ring_directions(12, theta_deg=(15, 30, 40))
    images = render_distant(surface, dirs)
    assert images.min() > 0  # truly unshadowed, so plain least squares is exact
    result = solve(images, DistantLights(dirs), method="lsq")
    err = angular_error_deg(result.normals, surface.normals)
    assert result.valid.all()
    assert err.mean() < 0.05
    assert_allclose(result.albedo, surface.albedo, rtol=1e-5)
    assert result.residual.max() < 1e-6


@pytest.mark.parametrize("method", ["lsq", "threshold", "irls"])
def test_every_method_exact_without_shadows(surface, method):
    dirs = ring_directions(24, theta_deg=(15, 30, 40))
    result = solve(render_distant(surface, dirs), DistantLights(dirs), method=method)
    assert result.valid.all()
    assert angular_error_deg(result.normals, surface.normals).max() < 0.01


def test_near_lamps_solved_as_near_below_01_deg(surface):
    top = surface.height.max()
    placed = Surface(
        surface.x,
        surface.y,
        surface.height - top,
        surface.normals,
        surface.albedo,
        surface.pitch_mm,
    )
    positions = ring_directions(16, theta_deg=(15, 30, 40)) * 80.0  # 80 mm: very near
    images = render_near(placed, positions, intensities=np.linspace(0.8, 1.2, 16))
    lights = NearLights(positions, intensities=np.linspace(0.8, 1.2, 16))
    points = np.stack([placed.x, placed.y, placed.height], axis=-1)
    result = solve(images, lights, pixels=points, method="lsq")
    assert result.valid.all()
    assert angular_error_deg(result.normals, surface.normals).mean() < 0.1
    assert_allclose(result.albedo, surface.albedo, rtol=1e-4)
    # Treated as distant, the same images are far off: the near model matters.
    as_distant = solve(images, DistantLights(positions / 80.0), method="lsq")
    assert angular_error_deg(as_distant.normals, surface.normals).mean() > 1.0


def test_robust_at_most_half_the_least_squares_error(surface):
    rng = np.random.default_rng(7)
    dirs = ring_directions(48, theta_deg=(25, 45, 65))
    images = render_distant(surface, dirs) + specular(surface, dirs, strength=0.8)
    cast = rng.random(images.shape) < 0.1
    images[cast] *= 0.05
    images = np.clip(images + rng.normal(0, 0.005, images.shape), 0, None).astype(np.float32)
    errors = {}
    for method in ("lsq", "threshold", "irls"):
        result = solve(images, DistantLights(dirs), method=method)
        assert result.valid.mean() > 0.99
        errors[method] = angular_error_deg(result.normals, surface.normals)[result.valid].mean()
    assert errors["irls"] <= 0.5 * errors["lsq"], errors
    assert errors["threshold"] <= 0.75 * errors["lsq"], errors


def test_colour_shares_normals_and_gives_albedo_per_channel(surface):
    dirs = ring_directions(12, theta_deg=(15, 30, 40))
    grey = render_distant(surface, dirs)
    tint = np.array([0.9, 0.6, 0.3])
    result = solve((grey[..., None] * tint).astype(np.float32), DistantLights(dirs), method="lsq")
    assert result.albedo.shape == (*surface.albedo.shape, 3)
    assert_allclose(result.albedo, surface.albedo[..., None] * tint, rtol=1e-5)
    assert angular_error_deg(result.normals, surface.normals).mean() < 0.01


@pytest.mark.parametrize("dtype", [np.float32, np.float64, np.uint8, np.uint16])
def test_dtype_policy_float32_maps(surface, dtype):
    dirs = ring_directions(6, theta_deg=(20, 40))
    images = render_distant(surface, dirs) * 0.9
    if np.issubdtype(dtype, np.integer):
        images = np.round(images * np.iinfo(dtype).max)
    result = solve(images.astype(dtype), DistantLights(dirs))
    for name in ("normals", "albedo", "condition", "residual"):
        assert getattr(result, name).dtype == np.float32, name
    assert result.reason.dtype == np.uint8 and result.valid.dtype == np.bool_
    assert_allclose(np.linalg.norm(result.normals, axis=-1), 1.0, atol=1e-6)
    tolerance = {np.uint8: 1.5, np.uint16: 0.01}.get(dtype, 1e-4)
    assert angular_error_deg(result.normals, surface.normals).mean() < tolerance


def test_integer_full_scale_counts_as_saturated():
    dirs = ring_directions(4, theta_deg=(30,))
    images = np.full((4, 2, 2), 1000, np.uint16)
    images[:2, 0, 0] = 65535  # two clipped lamps leave 2 < 3 usable
    images[0, 0, 1] = 65535  # one clipped lamp leaves 3
    result = solve(images, DistantLights(dirs), method="lsq")
    assert result.reason[0, 0] == Reason.SATURATED
    assert result.valid[0, 1] and result.lights_used[0, 1] == 3
    assert result.lights_used[1, 1] == 4


def test_mask_and_reason_counts(surface):
    dirs = ring_directions(6, theta_deg=(20, 40))
    mask = np.zeros(surface.albedo.shape, bool)
    mask[10:20, 5:50] = True
    result = solve(render_distant(surface, dirs), DistantLights(dirs), mask=mask)
    assert (result.reason[~mask] == Reason.MASKED).all()
    assert result.valid[mask].all()
    assert result.reason_counts() == {"OK": int(mask.sum()), "MASKED": int((~mask).sum())}
    assert (result.normals[~mask] == [0, 0, 1]).all() and (result.albedo[~mask] == 0).all()


def test_grid_positions_follow_the_texel_convention():
    from rig.geometry import texel_centers_mm

    grid = PixelGrid.for_sample(20.0, 8)
    assert_allclose(grid.positions_mm()[..., :2], texel_centers_mm(20.0, 8))


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda d, i: solve(i[:3], DistantLights(d)), "images: 3 images but 4 lights"),
        (lambda d, i: solve(i.astype(np.int32), DistantLights(d)), "dtype int32"),
        (lambda d, i: solve(i[..., None], DistantLights(d)), r"shape \(L, H, W\)"),
        (lambda d, i: solve(list(i), DistantLights(d)), "numpy array"),
        (lambda d, i: DistantLights(d[:2]), "at least 3 lights, got 2"),
        (lambda d, i: DistantLights(d * 2), r"directions\[0\] has length 2"),
        (lambda d, i: DistantLights(d * [1, 1, -1]), "below the sample plane"),
        (lambda d, i: DistantLights(d, intensities=[1, 1, 0, 1]), r"intensities\[2\]"),
        (lambda d, i: solve(i, DistantLights(d), method="ransac"), "method: 'ransac'"),
        (lambda d, i: solve(i, DistantLights(d), mask=np.ones((3, 3))), "mask: expected a bool"),
        (lambda d, i: solve(i, NearLights(d * 100)), "pixels: NearLights need"),
        (lambda d, i: NearLights(d * [1, 1, 0]), r"positions_mm\[0\] has z = 0"),
        (lambda d, i: solve(i, DistantLights(d), max_condition=0.5), "max_condition"),
    ],
)
def test_malformed_input_names_the_argument(call, match):
    dirs = ring_directions(4, theta_deg=(30,))
    images = np.ones((4, 5, 5), np.float32)
    with pytest.raises(PhotometricError, match=match) as info:
        call(dirs, images)
    assert isinstance(info.value, RigError)


def test_non_finite_float_image_is_reported_with_its_pixel():
    dirs = ring_directions(4, theta_deg=(30,))
    images = np.ones((4, 5, 5), np.float32)
    images[2, 3, 1] = np.nan
    with pytest.raises(PhotometricError, match=r"images\[2\] .* \(row 3, column 1\)"):
        solve(images, DistantLights(dirs))
    mask = np.ones((5, 5), bool)
    mask[3, 1] = False
    assert solve(images, DistantLights(dirs), mask=mask).valid.sum() == 24
