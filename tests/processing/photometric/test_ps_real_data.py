"""Real-data-shaped inputs: coloured lamps, clipped highlights, 0/255 masks.

Public photometric-stereo captures come as colour frames under lamps of
per-channel intensity (measured on a white target), with highlights the
sensor clipped, and masks stored as 8-bit images. The scenes are generated
here with a known answer.
"""

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from processing.photometric import (
    DistantLights,
    NearLights,
    PhotometricError,
    PixelGrid,
    Reason,
    solve,
)
from tests.processing.photometric.ps_synthetic import (
    angular_error_deg,
    bumps,
    render_distant,
    render_near,
    ring_directions,
)

DIRS = ring_directions(24, theta_deg=(15, 30, 40))
TINT = np.array([0.8, 0.55, 0.3])  # the sample's colour: albedo per channel × TINT


@pytest.fixture(scope="module")
def surface():
    return bumps(64, seed=11)


def lamp_colours(n_lights, seed=3):
    """(L, 3) per-channel intensities, warm to cool and of varying brightness."""
    rng = np.random.default_rng(seed)
    return rng.uniform(0.5, 1.5, (n_lights, 1)) * rng.uniform(0.6, 1.4, (n_lights, 3))


def colour_images(grey_per_lamp, intensities):
    """(L, H, W, 3): each lamp's grey shading times the sample tint and the lamp's colour."""
    return grey_per_lamp[..., None] * TINT * intensities[:, None, None, :]


@pytest.mark.parametrize("method", ["lsq", "irls"])
def test_per_channel_lamp_intensities_give_normals_and_albedo(surface, method):
    intensities = lamp_colours(len(DIRS))
    images = colour_images(render_distant(surface, DIRS), intensities).astype(np.float32)
    result = solve(images, DistantLights(DIRS, intensities), method=method)
    assert result.valid.all()
    assert angular_error_deg(result.normals, surface.normals).max() < 0.01
    assert_allclose(result.albedo, surface.albedo[..., None] * TINT, rtol=1e-4)
    # Taking the lamps as white (their brightness only) gets colour and normals wrong.
    white = solve(images, DistantLights(DIRS, intensities.mean(axis=1)), method=method)
    assert angular_error_deg(white.normals, surface.normals).mean() > 0.1


def test_per_channel_intensities_of_near_lamps(surface):
    positions = DIRS * 80.0
    intensities = lamp_colours(len(DIRS), seed=5)
    channels = [render_near(surface, positions, intensities[:, c]) for c in range(3)]
    images = np.stack(channels, axis=-1) * TINT
    grid = PixelGrid(surface.albedo.shape, surface.pitch_mm)
    points = np.stack([surface.x, surface.y, surface.height], axis=-1)
    result = solve(images, NearLights(positions, intensities), pixels=points, method="lsq")
    assert angular_error_deg(result.normals, surface.normals).max() < 0.01
    assert_allclose(result.albedo, surface.albedo[..., None] * TINT, rtol=1e-4)
    assert grid.shape == result.valid.shape


def clipped_capture(surface, intensities, dtype):
    """Colour frames with white highlights on 5 % of the observations, clipped at full scale."""
    images = colour_images(render_distant(surface, DIRS), intensities) * 0.6
    highlight = np.random.default_rng(7).random(images.shape[:3]) < 0.05
    images[highlight] = np.minimum(images[highlight] + 2.0, 1.0)
    if dtype == np.uint8:
        return np.round(images * 255).astype(np.uint8), highlight
    return images.astype(dtype), highlight


@pytest.mark.parametrize("dtype", [np.float32, np.uint8])
def test_clipped_highlights_are_excluded_before_the_lamp_colour_divides(surface, dtype):
    # Divided by the lamp's colour first, a clipped channel would no longer sit
    # at full scale: the levels are compared with the stored values.
    intensities = lamp_colours(len(DIRS))
    images, highlight = clipped_capture(surface, intensities, dtype)
    lights = DistantLights(DIRS, intensities)
    # float frames carry no full scale: say where they clip
    level = 1.0 if dtype == np.float32 else None
    result = solve(images, lights, method="lsq", saturation_level=level)
    assert_array_equal(result.lights_used, len(DIRS) - highlight.sum(axis=0))
    tolerance = 0.3 if dtype == np.uint8 else 1e-3  # uint8: quantisation
    assert angular_error_deg(result.normals, surface.normals).mean() < tolerance
    assert_allclose(result.albedo, 0.6 * surface.albedo[..., None] * TINT, rtol=0.03)
    kept = solve(images, lights, method="lsq", saturation_level=np.inf)
    assert angular_error_deg(kept.normals, surface.normals).mean() > 10 * tolerance


def test_a_clipping_level_per_light_and_channel(surface):
    # The blue channel of the first 6 lamps clips at 0.2 (a low-gain channel,
    # or a lamp measured on a darker exposure): only those observations go.
    intensities = lamp_colours(len(DIRS))
    images = colour_images(render_distant(surface, DIRS), intensities)
    levels = np.full((len(DIRS), 3), np.inf)
    levels[:6, 2] = 0.2
    images[:6, ..., 2] = np.minimum(images[:6, ..., 2], 0.2)
    result = solve(images, DistantLights(DIRS, intensities), method="lsq", saturation_level=levels)
    hit = (images[:6, ..., 2] >= 0.2).sum(axis=0)
    assert hit.max() > 0
    assert_array_equal(result.lights_used, len(DIRS) - hit)
    assert angular_error_deg(result.normals, surface.normals).max() < 0.01
    # one level per light holds for all its channels
    per_light = solve(
        images, DistantLights(DIRS, intensities), method="lsq", saturation_level=levels[:, 2]
    )
    all_channels = solve(
        images,
        DistantLights(DIRS, intensities),
        method="lsq",
        saturation_level=np.repeat(levels[:, 2:], 3, axis=1),
    )
    assert_array_equal(per_light.lights_used, all_channels.lights_used)
    assert (per_light.lights_used < result.lights_used).any()


@pytest.mark.parametrize("on", [1, 255])
def test_an_integer_mask_of_0_and_255_or_1_selects_like_a_bool_one(surface, on):
    images = render_distant(surface, DIRS).astype(np.float32)
    chosen = np.random.default_rng(2).random(surface.albedo.shape) < 0.2
    as_bool = solve(images, DistantLights(DIRS), method="lsq", mask=chosen)
    as_image = solve(images, DistantLights(DIRS), method="lsq", mask=(chosen * on).astype(np.uint8))
    assert_array_equal(as_image.reason, as_bool.reason)
    assert_array_equal(as_image.normals, as_bool.normals)
    assert (as_image.reason[~chosen] == Reason.MASKED).all()


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (
            lambda i: solve(i, DistantLights(DIRS), mask=np.full(i.shape[1:3], 7, np.uint8)),
            r"mask: an integer mask must hold only 0 and one 'on' value \(1 or 255\); got values 7",
        ),
        (
            lambda i: solve(i, DistantLights(DIRS, np.ones((len(DIRS), 3)))),
            r"per-channel intensities \(L, 3\) need colour images",
        ),
        (
            lambda i: DistantLights(DIRS, np.ones((len(DIRS), 4))),
            r"intensities: expected one per light, \(24,\), or one per light and colour channel",
        ),
        (
            lambda i: DistantLights(DIRS, -np.ones(len(DIRS))),
            r"intensities\[0\] = -1; lamp intensities must be finite and > 0",
        ),
        (
            lambda i: solve(i, DistantLights(DIRS), saturation_level=np.ones(5)),
            r"saturation_level: expected .* one per light \(24,\), got shape \(5,\)",
        ),
    ],
)
def test_bad_real_data_inputs_say_what_would_be_valid(call, match):
    with pytest.raises(PhotometricError, match=match):
        call(np.ones((len(DIRS), 4, 5), np.float32))
