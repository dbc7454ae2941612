"""Partial environment maps against a brute-force sum over every environment pixel."""

import numpy as np
import pytest

from render import RenderError
from render.environment import EnvironmentMap, synthetic_environment
from render.median_cut import median_cut_regions
from render.pem import blinn_half_width, lobe_level, pcf_radius, pem_radiance, region_pyramid
from rig.geometry import direction_vector

GLOSSY = {"albedo": 0.0, "specular": 1.0, "shininess": 40.0}
LAMBERT = {"albedo": 1.0}


def brute_force(environment, normal, view, *, albedo=0.0, specular=0.0, shininess=40.0):
    """Σ over every pixel L Δω (albedo cos θ + specular (n·h)^s), no occlusion."""
    vectors, solid = environment.pixel_directions()
    d = vectors.reshape(-1, 3)
    light = (environment.radiance.astype(np.float64) * solid[..., None]).reshape(-1, 3)
    cosine = np.clip(d @ normal, 0.0, None)
    half = d + view
    half /= np.linalg.norm(half, axis=1, keepdims=True)
    lobe = specular * np.clip(half @ normal, 0.0, None) ** shininess * (cosine > 0)
    return ((albedo * cosine + lobe)[:, None] * light).sum(axis=0) * environment.exposure


def surfaces(count=12):
    rng = np.random.default_rng(0)
    return [
        (direction_vector(rng.uniform(0, 60), rng.uniform(0, 360)),
         direction_vector(rng.uniform(0, 70), rng.uniform(0, 360)))
        for _ in range(count)
    ]  # fmt: skip


def mean_error(environment, count, shading, *, mip):
    errors = []
    for normal, view in surfaces():
        reference = brute_force(environment, normal, view, **shading)
        got = pem_radiance(environment, count, normal, view, mip=mip, **shading)
        assert np.all(np.isfinite(got))
        errors.append(np.abs(got - reference).sum() / np.abs(reference).sum())
    return float(np.mean(errors))


@pytest.mark.parametrize("name", ["window", "studio"])
def test_lambert_error_falls_with_the_region_count(name):
    environment = synthetic_environment(name, height=32)
    point = [mean_error(environment, k, LAMBERT, mip=False) for k in (1, 4, 64)]
    mip = [mean_error(environment, k, LAMBERT, mip=True) for k in (1, 64)]
    assert point[0] > point[1] > point[2]
    assert mip[1] < mip[0] and mip[1] < 0.01


@pytest.mark.parametrize("name", ["sky", "window", "studio"])
def test_glossy_lobe_is_better_with_the_mip_level_than_with_point_lights(name):
    environment = synthetic_environment(name, height=32)
    for count in (4, 16, 64):
        mip = mean_error(environment, count, GLOSSY, mip=True)
        point = mean_error(environment, count, GLOSSY, mip=False)
        assert mip < 0.5 * point and mip < 0.2, (count, mip, point)


def test_sharper_lobes_read_finer_levels():
    levels = [lobe_level(blinn_half_width(s), 32) for s in (1.0, 10.0, 100.0, 1e4)]
    assert levels == sorted(levels, reverse=True) and levels[0] > levels[-1] == 0
    assert lobe_level(np.pi / 3, 32) == 3  # a 60° lobe spans 8 pixels of π/32


def test_every_level_keeps_the_region_light():
    environment = synthetic_environment("sky", height=32)
    _, solid = environment.pixel_directions()
    for region in median_cut_regions(environment, 8):
        r0, r1, c0, c1 = region
        total = (environment.radiance[r0:r1, c0:c1] * solid[r0:r1, :, None]).sum(axis=(0, 1))
        for level in range(6):
            directions, light = region_pyramid(environment, region, level)
            np.testing.assert_allclose(light.sum(axis=0), total, rtol=1e-9)
            np.testing.assert_allclose(np.linalg.norm(directions, axis=1), 1.0, rtol=1e-12)


def test_larger_regions_cast_softer_shadows():
    environment = synthetic_environment("window", height=32)
    regions = median_cut_regions(environment, 16)
    sizes = [(r1 - r0) * (c1 - c0) for r0, r1, c0, c1 in regions]
    small, large = regions[int(np.argmin(sizes))], regions[int(np.argmax(sizes))]
    assert pcf_radius(environment, large, 0.01, 0.5) > pcf_radius(environment, small, 0.01, 0.5)
    assert pcf_radius(environment, small, 1.0, 1e-6) == 1.0


def test_black_environment_gives_black():
    environment = EnvironmentMap(np.zeros((16, 32, 3), np.float32))
    got = pem_radiance(environment, 8, (0, 0, 1), (0, 0, 1), specular=1.0)
    np.testing.assert_array_equal(got, 0.0)


@pytest.mark.parametrize(
    ("arguments", "field"),
    [
        ({"shininess": 0.0}, "shininess"),
        ({"specular": -1.0}, "specular"),
        ({"albedo": float("nan")}, "albedo"),
        ({"normal": (0, 0, 0)}, "normal"),
        ({"view": (1, 2)}, "view"),
        ({"count": 3}, "count"),
    ],
)
def test_bad_input_names_the_field(arguments, field):
    call = {"count": 4, "normal": (0, 0, 1), "view": (0, 0, 1)} | arguments
    environment = synthetic_environment("sky", height=16)
    with pytest.raises(RenderError, match=field):
        pem_radiance(environment, call.pop("count"), call.pop("normal"), call.pop("view"), **call)
