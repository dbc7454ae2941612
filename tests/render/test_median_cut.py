"""Median-cut lights of an environment, and the point-light renderer under them."""

import numpy as np
import pytest

from processing.btf import interpolate
from render import Camera, Renderer, RenderError
from render.environment import EnvironmentMap, synthetic_environment
from render.pem.median_cut import environment_lights, median_cut, render_median_cut
from rig.geometry import direction_angles, direction_vector
from tests.render.conftest import SAMPLE_MM, N, material, tilted_quad


@pytest.mark.parametrize("name", ["sky", "window", "studio"])
@pytest.mark.parametrize("count", [1, 4, 32])
def test_regions_keep_all_the_light(name, count):
    env = synthetic_environment(name, height=16).with_view(rotation_deg=25.0)
    directions, irradiance = median_cut(env, count)
    _, solid = env.pixel_directions()
    total = (env.radiance.astype(np.float64) * solid[..., None]).sum(axis=(0, 1))
    np.testing.assert_allclose(irradiance.sum(axis=0), total, rtol=1e-9)
    assert len(directions) <= count
    np.testing.assert_allclose(np.linalg.norm(directions, axis=1), 1.0)


def test_bright_areas_get_small_regions_and_the_sun_the_most_light():
    env = synthetic_environment("sky", height=32)
    directions, irradiance = median_cut(env, 16)
    theta, phi = direction_angles(directions[np.argmax(irradiance.sum(axis=1))])
    assert abs(theta - 40.0) < 3 and abs(phi - 120.0) < 6
    # The sun holds most of the light: a quarter of the lights within 10° of it.
    near_sun = np.degrees(np.arccos(directions @ direction_vector(40.0, 120.0))) < 10
    assert near_sun.sum() >= 4


def test_black_environment_gives_no_lights_and_a_black_image(pca_model):
    black = EnvironmentMap(np.zeros((8, 16, 3), np.float32))
    assert environment_lights(black, 8) == []
    mesh, _ = tilted_quad((0.0, 0.0))
    camera = Camera.orthographic((0, 0, 100), (0, 0, 0), height=SAMPLE_MM, size=(N, N))
    with Renderer(material(pca_model), mesh, shadows=False) as renderer:
        assert not render_median_cut(renderer, camera, black, count=8).any()


def test_gpu_sums_the_lights_like_the_cpu(pca_model):
    """More lights than one pass holds: passes summed, each light × the BTF at its local
    direction (``processing.btf.interpolate``), the exposure applied — within float16."""
    view_deg = (23.0, 41.0)
    mesh, frame = tilted_quad(view_deg)
    env = synthetic_environment("studio", height=16).with_view(exposure=0.25)
    camera = Camera.orthographic(
        (0, 0, 100), (0, 0, 0), up=(0, 1, 0), height=SAMPLE_MM, size=(N, N)
    )
    with Renderer(material(pca_model), mesh, shadows=False) as renderer:
        image = render_median_cut(renderer, camera, env, count=16)
    expected = np.zeros((N, N, 3))
    for light in environment_lights(env, 16):
        local = frame.T @ light.unit_direction
        if local[2] > 0:
            theta, phi = direction_angles(local)
            texture = interpolate(pca_model, view_deg=view_deg, light_deg=(theta, phi))
            expected += light.emission * texture
    assert len(environment_lights(env, 16)) > 8 and expected.max() > 0
    np.testing.assert_allclose(image, expected, atol=2.0**-10 * np.abs(expected).max(), rtol=0)


def test_count_must_be_a_power_of_two():
    with pytest.raises(RenderError, match="power of 2"):
        median_cut(synthetic_environment("sky", height=8), 12)
