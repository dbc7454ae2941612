"""Partial environment maps against a brute-force sum over every environment pixel."""

import numpy as np
import pytest

from render import RenderError
from render.environment import EnvironmentMap, synthetic_environment
from render.pem.median_cut import median_cut_regions
from render.pem.regions import (
    MAX_LOBE_TEXELS,
    blinn_half_width,
    lobe_level,
    partial_maps,
    pem_radiance,
    region_pyramid,
)
from rig.geometry import direction_vector

GLOSSY = {"albedo": 0.0, "specular": 1.0, "shininess": 40.0}
LAMBERT = {"albedo": 1.0}
GLOSSY_PART = {"specular": 0.5, "shininess": 40.0}


def brute_force(environment, normal, view, *, surface=None, albedo=0.0, specular=0.0,
                shininess=40.0):  # fmt: skip
    """(…, 3): Σ over every pixel above the horizon of ``surface`` (``normal`` by default) of
    L Δω (albedo cos θ + specular (n·h)^s), no occlusion; ``normal`` (…, 3), ``view`` (3,)
    unit, ``albedo`` a number or (…, 3)."""
    vectors, solid = environment.pixel_directions()
    d = vectors.reshape(-1, 3)
    light = (environment.radiance.astype(np.float64) * solid[..., None]).reshape(-1, 3)
    normal = np.asarray(normal, np.float64)
    cosine = np.clip(normal @ d.T, 0.0, None)
    if surface is not None:
        cosine *= d @ np.asarray(surface, np.float64) > 0
    half = d + view
    half /= np.linalg.norm(half, axis=1, keepdims=True)
    lobe = specular * np.clip(normal @ half.T, 0.0, None) ** shininess * (cosine > 0)
    return (np.asarray(albedo) * (cosine @ light) + lobe @ light) * environment.exposure


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


def disc_environment(radius_deg, *, centre_deg=(30.0, 90.0), height=64, power=1.0):
    """Black but for a uniform disc of ``radius_deg`` at ``centre_deg`` (θ, φ) carrying
    ``power`` (Σ L Δω)."""
    black = EnvironmentMap(np.zeros((height, 2 * height, 3), np.float32))
    vectors, solid = black.pixel_directions()
    angle = np.degrees(np.arccos(np.clip(vectors @ direction_vector(*centre_deg), -1, 1)))
    inside = angle <= radius_deg
    radiance = np.where(inside, power / (solid * inside).sum(), 0.0)
    return EnvironmentMap(np.repeat(radiance[..., None], 3, axis=2).astype(np.float32))


@pytest.mark.parametrize("radius_deg", [8.0, 20.0])
def test_a_disc_region_has_the_disc_radius(radius_deg):
    """One region holding a uniform disc: √2 × its RMS angle is the disc's radius (within the
    pixels' 2.8° steps), so its shadow is as soft as the disc's."""
    maps = partial_maps(disc_environment(radius_deg), 1)
    assert len(maps.angular_radius) == 1
    assert np.degrees(maps.angular_radius[0]) == pytest.approx(radius_deg, abs=1.5)
    np.testing.assert_allclose(maps.directions[0], direction_vector(30.0, 90.0), atol=0.01)


def test_sharp_lobes_on_large_maps_read_a_coarser_level():
    environment = synthetic_environment("studio", height=128)
    sharp = partial_maps(environment, 16, shininess=1e4)
    assert sharp.glossy[:, 1].sum() <= MAX_LOBE_TEXELS < _texels_at(environment, 16, 0)
    assert sharp.levels[1] > lobe_level(blinn_half_width(1e4), 128) == 0


def _texels_at(environment, count, level):
    regions = median_cut_regions(environment, count)
    return sum(len(region_pyramid(environment, region, level)[0]) for region in regions)


def test_surfaces_are_shaded_at_once_as_one_by_one():
    environment = synthetic_environment("window", height=16)
    pairs = surfaces(4)
    normals, views = np.array([n for n, _ in pairs]), np.array([v for _, v in pairs])
    albedo = np.linspace(0.2, 0.8, 12).reshape(4, 3)
    together = pem_radiance(environment, 8, normals, views, albedo=albedo, **GLOSSY_PART)
    for i in range(4):
        alone = pem_radiance(environment, 8, normals[i], views[i], albedo=albedo[i], **GLOSSY_PART)
        np.testing.assert_allclose(together[i], alone, rtol=1e-12)


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
