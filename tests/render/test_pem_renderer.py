"""Partial environment maps in the GL renderer against the CPU sums, and their soft shadows.

The plane is the texel-exact quad (``conftest.tilted_quad``, 16² pixels, one per
texel) under bumpy photometric-stereo normals, so each pixel has its own
normal. Tolerance of GL against :func:`render.pem.pem_radiance`: both read the
same float32 numbers (the PS maps and the texel table are float32 textures —
the table cannot be float16: a sun's texel passes float16's 65504), and the GPU
sums at most a few hundred texels in float32, so they agree to 10⁻⁴ of the
brightest pixel; reading the wrong level (the point lights) misses by 5–80 %.
"""

import numpy as np
import pytest

from render import Camera, Renderer, RenderError
from render.environment import EnvironmentMap, synthetic_environment
from render.meshes import Mesh
from render.pem import pem_radiance
from render.pem.median_cut import render_median_cut
from render.pem.renderer import PemRenderer
from render.texel_view import texel_camera
from rig.material import PsView
from tests.render.conftest import SAMPLE_MM, N, material, ps_view, tilted_quad
from tests.render.test_pem import brute_force, disc_environment

VIEW_DEG = (35.0, 60.0)
#: The quad's shading frame: its normal is FRAME[:, 2].
FRAME = tilted_quad(VIEW_DEG)[1]
GLOSSY = {"specular": 1.0, "shininess": 40.0}


def render_plane(environment, count, *, mip=True, specular=0.0, shininess=40.0, btf=None):
    mesh, _ = tilted_quad(VIEW_DEG)
    lit = material(btf) if btf is not None else material(ps=ps_view())
    with PemRenderer(lit, mesh, shadows=False, mip=mip, specular=specular,
                     shininess=shininess) as renderer:  # fmt: skip
        return renderer.render_environment(texel_camera(SAMPLE_MM, N), environment, count=count)


def plane_normals() -> np.ndarray:
    """(N, N, 3) the bumped normals in the scene frame, as the pixels see them."""
    return ps_view().normals.astype(np.float64) @ FRAME.T


def relative_error(image, reference) -> float:
    assert np.all(np.isfinite(image))
    return float(np.abs(image - reference).sum() / np.abs(reference).sum())


@pytest.mark.parametrize("name", ["sky", "window", "studio"])
@pytest.mark.parametrize("shading", [{"specular": 0.0}, GLOSSY], ids=["lambert", "glossy"])
def test_gl_equals_the_cpu_sum_of_the_partial_maps(name, shading):
    environment = synthetic_environment(name, height=32)
    image = render_plane(environment, 16, **shading)
    expected = pem_radiance(environment, 16, plane_normals(), np.array([0.0, 0.0, 1.0]),
                            surface=FRAME[:, 2], albedo=ps_view().albedo.astype(np.float64),
                            **shading)  # fmt: skip
    np.testing.assert_allclose(image, expected, atol=1e-4 * np.abs(expected).max(), rtol=0)


def test_a_btf_takes_each_region_whole_from_its_direction(pca_model):
    """Under a BTF the regions are the median-cut lights (see render.pem.renderer)."""
    environment = synthetic_environment("studio", height=16)
    image = render_plane(environment, 16, btf=pca_model)
    mesh, _ = tilted_quad(VIEW_DEG)
    with Renderer(material(pca_model), mesh, shadows=False) as renderer:
        expected = render_median_cut(renderer, texel_camera(SAMPLE_MM, N), environment, count=16)
    assert np.abs(expected).max() > 0
    np.testing.assert_allclose(image, expected, atol=1e-5 * np.abs(expected).max(), rtol=0)


def test_under_a_btf_the_ps_layer_adds_only_its_lobe(pca_model):
    """BTF + PS: the BTF takes the regions whole, the PS lobe reads its level (no albedo term,
    the BTF holds the diffuse shading)."""
    environment = synthetic_environment("studio", height=16)
    mesh, _ = tilted_quad(VIEW_DEG)
    both = material(pca_model, ps=ps_view())
    camera = texel_camera(SAMPLE_MM, N)
    with PemRenderer(both, mesh, shadows=False, **GLOSSY) as renderer:
        image = renderer.render_environment(camera, environment, count=16)
    with Renderer(both, mesh, shadows=False) as renderer:
        btf_part = render_median_cut(renderer, camera, environment, count=16)
    lobe = pem_radiance(environment, 16, plane_normals(), np.array([0.0, 0.0, 1.0]),
                        surface=FRAME[:, 2], albedo=0.0, **GLOSSY)  # fmt: skip
    assert np.abs(lobe).max() > 0.1 * np.abs(btf_part).max()
    np.testing.assert_allclose(image, btf_part + lobe, atol=1e-4 * np.abs(image).max(), rtol=0)


def _error_against_every_pixel(environment, count, *, mip, **lobe):
    """Relative L1 error of the plane's image against the sum over every pixel: the albedo
    part alone, or with ``lobe`` (specular, shininess) the lobe part alone."""
    albedo = 0.0 if lobe else ps_view().albedo.astype(np.float64)
    reference = brute_force(environment, plane_normals(), np.array([0.0, 0.0, 1.0]),
                            surface=FRAME[:, 2], albedo=albedo, **lobe)  # fmt: skip
    image = render_plane(environment, count, mip=mip, **lobe)
    if lobe:
        image = image - render_plane(environment, count, mip=mip)
    return relative_error(image, reference)


@pytest.mark.parametrize("name", ["window", "studio"])
def test_gl_error_against_every_pixel_falls_with_the_region_count(name):
    environment = synthetic_environment(name, height=32)
    errors = [_error_against_every_pixel(environment, k, mip=True) for k in (1, 4, 16, 64)]
    assert errors == sorted(errors, reverse=True) and errors[-1] < 0.01, errors


@pytest.mark.parametrize("name", ["sky", "window", "studio"])
def test_gl_glossy_lobe_is_better_at_its_level_than_as_point_lights(name):
    environment = synthetic_environment(name, height=32)
    mip = _error_against_every_pixel(environment, 16, mip=True, **GLOSSY)
    point = _error_against_every_pixel(environment, 16, mip=False, **GLOSSY)
    assert mip < 0.5 * point and mip < 0.15, (mip, point)


def _quad(x0, x1, y0, y1, z) -> np.ndarray:
    return np.array([[x0, y0, z], [x1, y0, z], [x1, y1, z], [x0, y1, z]], np.float32)


def blocker_scene(height: float) -> Mesh:
    """Ground z = 0 over ±60 and, ``height`` above it, a blocker over x ≥ 0."""
    positions = np.vstack([_quad(-60, 60, -60, 60, 0.0), _quad(0, 60, -60, 60, height)])
    return Mesh(
        positions=positions, normals=np.tile([0.0, 0.0, 1.0], (8, 1)).astype(np.float32),
        uvs=(positions[:, :2] + 60).astype(np.float32),
        tangents=np.tile([1.0, 0.0, 0.0, 1.0], (8, 1)).astype(np.float32),
        faces=np.array([[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]], np.uint32), name="blocker",
    )  # fmt: skip


def grey_ps() -> PsView:
    return PsView(
        name="cam0", normals=np.tile([0.0, 0.0, 1.0], (N, N, 1)).astype(np.float32),
        albedo=np.full((N, N, 3), 0.5, np.float32), valid=np.ones((N, N), bool),
        reason=np.zeros((N, N), np.uint8), height_mm=np.zeros((N, N), np.float32),
        view_deg=(0.0, 0.0),
    )  # fmt: skip


#: The ground beside the blocker, x from −28 to 0, seen from above.
GROUND_CAMERA = Camera.orthographic((-14, 0, 100), (-14, 0, 0), up=(0, 1, 0), height=28.0,
                                    size=(64, 64))  # fmt: skip


def penumbra_width(radius_deg: float, height: float) -> float:
    """10–90 % width (scene units) of the shadow edge the blocker casts under one region,
    a disc of ``radius_deg`` at θ = 30° (its edge at x = −height · tan 30°)."""
    environment = disc_environment(radius_deg, centre_deg=(30.0, 0.0))
    with PemRenderer(material(ps=grey_ps()), blocker_scene(height), occluder_mm=height) as r:
        image = r.render_environment(GROUND_CAMERA, environment, count=1)
    profile = image[..., 1].mean(axis=0)
    profile = profile / profile[:5].mean()
    x = -28 + (np.arange(64) + 0.5) * 28 / 64
    assert profile.min() < 0.05 and np.all(np.diff(profile) <= 1e-6)  # lit, then shadowed

    def crossing(level):
        i = int(np.flatnonzero(profile < level)[0])
        step = (profile[i - 1] - level) / (profile[i - 1] - profile[i])
        return x[i - 1] + step * (x[i] - x[i - 1])

    return float(crossing(0.1) - crossing(0.9))


def test_the_penumbra_grows_with_the_region_extent():
    """A disc light of radius ρ casts a 10–90 % penumbra of 1.38 h tan ρ from an edge h above;
    the region's kernel gives it within 25 %, and 4 times wider at 20° than at 5°."""
    height = 10.0
    widths = {r: penumbra_width(r, height) for r in (5.0, 20.0)}
    for r, width in widths.items():
        assert width == pytest.approx(1.38 * height * np.tan(np.radians(r)), rel=0.25)
    assert widths[20.0] > 3 * widths[5.0]


@pytest.mark.parametrize("case", ["black", "sun 1e5"])
def test_a_black_map_and_a_blinding_sun_stay_finite(case):
    if case == "black":
        environment = EnvironmentMap(np.zeros((16, 32, 3), np.float32))
    else:
        sky = synthetic_environment("sky", height=32)
        radiance = np.where(sky.radiance > 100, sky.radiance * 1e5, sky.radiance)
        environment = EnvironmentMap(radiance.astype(np.float32))
    with PemRenderer(material(ps=grey_ps()), blocker_scene(10.0), **GLOSSY) as renderer:
        image = renderer.render_environment(GROUND_CAMERA, environment, count=16)
    assert np.all(np.isfinite(image))
    assert (image.max() == 0) if case == "black" else (image.max() > 1e5)


def test_a_negative_occluder_height_is_refused():
    with pytest.raises(RenderError, match="occluder_mm"):
        PemRenderer(material(ps=grey_ps()), blocker_scene(10.0), occluder_mm=-1.0)


def test_the_partial_maps_are_made_once_per_map_rotation_and_count():
    sky = synthetic_environment("sky", height=16)
    with PemRenderer(material(ps=grey_ps()), blocker_scene(10.0)) as renderer:
        first = renderer.maps_for(sky, 8)
        assert renderer.maps_for(sky.with_view(rotation_deg=0.0), 8) is first
        turned = renderer.maps_for(sky.with_view(rotation_deg=90.0), 8)
        assert turned is not first and renderer.maps_for(sky, 16) is not turned
        np.testing.assert_allclose(turned.light, first.light)  # the same light, turned
        assert not np.allclose(turned.directions, first.directions)
