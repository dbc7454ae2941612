"""Environment maps: files (.hdr through OpenCV, .exr through OpenEXR), rotation, checks."""

import cv2
import numpy as np
import pytest

from render import RenderError
from render.environment import (
    SYNTHETIC_ENVIRONMENTS,
    EnvironmentMap,
    read_environment,
    synthetic_environment,
)
from render.output import write_exr
from rig.geometry import direction_vector


@pytest.mark.parametrize("name", SYNTHETIC_ENVIRONMENTS)
def test_synthetic_environments_are_finite_hdr_lat_long(name):
    env = synthetic_environment(name, height=16)
    assert env.radiance.shape == (16, 32, 3)
    assert np.all(np.isfinite(env.radiance)) and env.radiance.min() >= 0
    assert env.radiance.max() / max(env.radiance[env.radiance > 0].min(), 1e-30) > 10


def test_pixel_solid_angles_cover_the_sphere():
    env = synthetic_environment("sky", height=16)
    _, solid = env.pixel_directions()
    np.testing.assert_allclose(solid.sum() * 32, 4 * np.pi, rtol=1e-12)


def test_sun_is_where_the_sky_puts_it():
    env = synthetic_environment("sky", height=32)
    sun = env.lookup(direction_vector(40.0, 120.0))
    assert sun.max() > 1000 * env.lookup(direction_vector(0.0, 0.0)).max()


def test_rotation_turns_the_map_about_the_vertical():
    env = synthetic_environment("window", height=16)  # the window spans φ 60–120°
    window = direction_vector(65.0, 90.0)
    turned = env.with_view(rotation_deg=90.0)
    assert env.lookup(window).max() == 4.0
    assert turned.lookup(window).max() < 0.1
    assert turned.lookup(direction_vector(65.0, 180.0)).max() == 4.0


@pytest.mark.parametrize("suffix", [".hdr", ".exr"])
def test_files_read_back(tmp_path, suffix):
    env = synthetic_environment("studio", height=8)
    path = tmp_path / f"studio{suffix}"
    if suffix == ".hdr":
        assert cv2.imwrite(str(path), np.ascontiguousarray(env.radiance[..., ::-1]))
    else:
        write_exr(path, env.radiance)
    read = read_environment(path, exposure=2.0, rotation_deg=15.0)
    # Radiance HDR keeps an 8-bit mantissa per pixel (shared exponent): 1 % relative.
    np.testing.assert_allclose(read.radiance, env.radiance, rtol=0.01, atol=1e-6)
    assert (read.exposure, read.rotation_deg) == (2.0, 15.0)


def test_bad_maps_name_what_is_wrong(tmp_path):
    with pytest.raises(RenderError, match=r"\(H, 2H, 3\)"):
        EnvironmentMap(np.ones((8, 8, 3), np.float32))
    with pytest.raises(RenderError, match="finite and ≥ 0"):
        EnvironmentMap(np.full((4, 8, 3), -1.0, np.float32))
    with pytest.raises(RenderError, match="exposure"):
        EnvironmentMap(np.ones((4, 8, 3), np.float32), exposure=0.0)
    with pytest.raises(RenderError, match=r"\.hdr or \.exr"):
        read_environment(tmp_path / "sky.png")
    with pytest.raises(RenderError, match="no such"):
        read_environment(tmp_path / "sky.hdr")
    (tmp_path / "broken.exr").write_bytes(b"not an exr")
    with pytest.raises(RenderError, match=r"broken\.exr"):
        read_environment(tmp_path / "broken.exr")
    with pytest.raises(RenderError, match="synthetic ones are"):
        synthetic_environment("beach")


def test_mean_lookup_keeps_the_light_of_the_map_at_every_width():
    """Each level's pixels times their solid angles sum to the map's light (within float64
    rounding), a uniform map reads as itself at any width, and at a width below a pixel
    the lookup at a pixel's centre reads that pixel."""
    sky = synthetic_environment("sky", height=32).with_view(rotation_deg=33.0)
    rng = np.random.default_rng(3)
    directions = rng.normal(size=(500, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    total = (sky.radiance.astype(np.float64) * sky.pixel_directions()[1][..., None]).sum((0, 1))
    for level in sky._means:
        h = level.shape[0]
        _, solid = EnvironmentMap(np.zeros((h, 2 * h, 3), np.float32)).pixel_directions()
        np.testing.assert_allclose((level * solid[..., None]).sum((0, 1)), total, rtol=1e-12)
    assert [m.shape[0] for m in sky._means] == [32, 16, 8, 4, 2]
    uniform = EnvironmentMap(np.full((16, 32, 3), 0.7, np.float32))
    for width in (0.01, 0.3, 3.0):
        np.testing.assert_allclose(uniform.mean_lookup(directions, width), 0.7, rtol=1e-6)
    centres, _ = sky.pixel_directions()  # rotation applied
    np.testing.assert_allclose(sky.mean_lookup(centres, 1e-3), sky.radiance, rtol=1e-5, atol=1e-6)
