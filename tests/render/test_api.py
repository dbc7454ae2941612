"""The renderer's inputs: cameras, lights, layers — and bad ones named."""

import dataclasses

import numpy as np
import pytest

from processing.btf import interpolate
from render import MAX_LIGHTS, Camera, DirectionalLight, PointLight, Renderer, RenderError
from render.lights import MAX_EMISSION
from render.meshes import plane
from rig.geometry import direction_angles, direction_vector
from tests.render.conftest import SAMPLE_MM, material, ps_view, tilted_quad
from tests.render.test_exact import FLOAT16_EPS, frontal_camera, numpy_ps_shading, render_at


def test_point_light_falls_off_as_inverse_square(pca_model):
    """A point light straight above at height h gives 1/h² of a directional light there."""
    mesh, _ = tilted_quad((0.0, 0.0))
    with Renderer(material(pca_model), mesh, shadows=False) as renderer:
        far = renderer.render(frontal_camera(), [PointLight((0, 0, 4000.0), intensity=4000.0**2)])
        near = renderer.render(frontal_camera(), [PointLight((0, 0, 2000.0), intensity=4000.0**2)])
    # At 4 m the 20 mm sample sees the lamp within 0.2° of the pole: the frontal light.
    expected = interpolate(pca_model, view_deg=(0, 0), light_deg=(0, 0))
    np.testing.assert_allclose(far, expected, rtol=1e-3, atol=FLOAT16_EPS)
    np.testing.assert_allclose(near, 4 * far, rtol=1e-3, atol=FLOAT16_EPS)


def test_several_lights_add_up(svd_model):
    lights = [(20.0, 40.0), (55.0, 190.0), (70.0, 300.0)]
    mesh, frame = tilted_quad((35.0, 80.0))
    colours = [(1.0, 0.5, 0.25), (0.2, 1.0, 0.2), (1.0, 1.0, 1.0)]
    with Renderer(material(svd_model), mesh, shadows=False) as renderer:
        image = renderer.render(frontal_camera(), [
            DirectionalLight(tuple(frame @ direction_vector(*d)), colour=c, intensity=2.0)
            for d, c in zip(lights, colours, strict=True)
        ])  # fmt: skip
    expected = sum(
        2.0 * np.asarray(c) * interpolate(svd_model, view_deg=(35.0, 80.0), light_deg=d)
        for d, c in zip(lights, colours, strict=True)
    )
    np.testing.assert_allclose(image, expected, atol=FLOAT16_EPS * np.abs(expected).max())


def test_ps_under_the_btf_adds_only_the_specular_lobe(pca_model):
    """With both layers the BTF gives the diffuse shading, the PS normals the highlight."""
    ps, view_deg, light_deg = ps_view(), (30.0, 120.0), (40.0, 300.0)
    both = render_at(material(pca_model, ps=ps), view_deg, light_deg, specular=0.4, shininess=8.0)
    btf = interpolate(pca_model, view_deg=view_deg, light_deg=light_deg)
    lobe = numpy_ps_shading(
        ps, direction_vector(*view_deg), direction_vector(*light_deg), specular=0.4, shininess=8.0
    ) - numpy_ps_shading(
        ps, direction_vector(*view_deg), direction_vector(*light_deg), specular=0.0, shininess=8.0
    )
    assert lobe.max() > 0.05
    np.testing.assert_allclose(both, btf + lobe, atol=FLOAT16_EPS * np.abs(btf).max() + 1e-5)


def test_uv_tiling_repeats_the_sample_per_tile_mm(pca_model):
    """tile_mm = half the sample: the quad shows the sample twice across, each at half size."""
    mesh, _ = tilted_quad((0.0, 0.0))
    light = [DirectionalLight((0, 0, 1))]
    camera = Camera.orthographic((0, 0, 100), (0, 0, 0), up=(0, 1, 0), height=SAMPLE_MM,
                                 size=(32, 32))  # fmt: skip
    with Renderer(material(pca_model), mesh, tile_mm=SAMPLE_MM / 2, shadows=False) as r:
        tiled = r.render(camera, light)
    np.testing.assert_allclose(tiled[:16, :16], tiled[16:, 16:], atol=1e-6)
    expected = interpolate(pca_model, view_deg=(0, 0), light_deg=(0, 0))
    np.testing.assert_allclose(tiled[:16, :16], expected, atol=FLOAT16_EPS * expected.max())


def test_camera_and_light_errors_name_the_field():
    with pytest.raises(RenderError, match="fov_deg = 180"):
        Camera.perspective((0, 0, 1), fov_deg=180)
    with pytest.raises(RenderError, match="eye and target are the same"):
        Camera.perspective((1, 2, 3), (1, 2, 3))
    with pytest.raises(RenderError, match="size"):
        Camera.orthographic((0, 0, 1), size=(0, 10))
    with pytest.raises(RenderError, match="height"):
        Camera.orthographic((0, 0, 1), height=-1)
    with pytest.raises(RenderError, match="eye"):
        Camera.perspective((0, np.nan, 1))
    with pytest.raises(RenderError, match="point light position"):
        PointLight((0, 1))
    with pytest.raises(RenderError, match="directional light direction"):
        DirectionalLight((0, 0, 0))
    with pytest.raises(RenderError, match="intensity"):
        DirectionalLight((0, 0, 1), intensity=-1)
    with pytest.raises(RenderError, match="colour"):
        PointLight((0, 0, 1), colour=(1, 1))
    with pytest.raises(RenderError, match="at most 1e"):
        PointLight((0, 0, 1), colour=(1, 2, 1), intensity=MAX_EMISSION)


def test_renderer_errors_name_the_option(pca_model):
    mesh = plane(size_mm=SAMPLE_MM)
    with pytest.raises(RenderError, match=r"cannot render layers \['ps'\]"):
        Renderer(material(pca_model), mesh, layers=("ps",))
    with pytest.raises(RenderError, match="valid are"):
        Renderer(material(pca_model), mesh, layers=("mdf",))
    with pytest.raises(RenderError, match="light_method = 'cubic'"):
        Renderer(material(pca_model), mesh, light_method="cubic")
    with pytest.raises(RenderError, match="tile_mm = 0"):
        Renderer(material(pca_model), mesh, tile_mm=0)
    with pytest.raises(RenderError, match="valid view slot"):
        Renderer(material(pca_model, slot_valid=np.zeros(len(pca_model.view_dirs_deg), bool)),
                 mesh)  # fmt: skip
    two_channels = dataclasses.replace(
        pca_model, mean=pca_model.mean[..., :2], basis=pca_model.basis[..., :2]
    )
    with pytest.raises(RenderError, match=r"2 channels per texel; .* 1 .* or 3"):
        Renderer(material(two_channels), mesh)
    too_many = [DirectionalLight((0, 0, 1))] * (MAX_LIGHTS + 1)
    with (
        Renderer(material(pca_model), mesh, shadows=False) as renderer,
        pytest.raises(RenderError, match=f"up to {MAX_LIGHTS}"),
    ):
        renderer.render(frontal_camera(), too_many)


def test_no_lights_give_a_black_image(pca_model):
    with Renderer(material(pca_model), plane(size_mm=SAMPLE_MM)) as renderer:
        image = renderer.render(frontal_camera(), [])
    assert image.shape == (16, 16, 3)
    assert not image.any()


def test_the_back_of_a_surface_shows_the_material_turned_over(pca_model):
    """Seen from below, the quad's frame is (t, −b, −n): right-handed, the sample turned over
    about its u axis; the camera below sees the texel columns mirrored."""
    mesh, _ = tilted_quad((0.0, 0.0))
    below = Camera.orthographic((0, 0, -100), (0, 0, 0), up=(0, 1, 0), height=SAMPLE_MM,
                                size=(16, 16))  # fmt: skip
    to_light = np.array([0.3, 0.4, -np.sqrt(0.75)])
    with Renderer(material(pca_model), mesh, shadows=False) as renderer:
        image = renderer.render(below, [DirectionalLight(tuple(to_light))])
    local = to_light * [1.0, -1.0, -1.0]
    light_deg = np.ravel(direction_angles(local))
    expected = interpolate(pca_model, view_deg=(0.0, 0.0), light_deg=light_deg)[:, ::-1]
    np.testing.assert_allclose(image, expected, atol=FLOAT16_EPS * np.abs(expected).max())


def test_a_framebuffer_beyond_the_context_is_named_with_its_limit():
    from render.core.gl import gl_context, image_framebuffer

    ctx = gl_context()
    largest = min(ctx.info["GL_MAX_RENDERBUFFER_SIZE"], *ctx.info["GL_MAX_VIEWPORT_DIMS"])
    limit = rf"image size {largest + 1}×1: .*\({largest}×{largest} pixels at most\)"
    with pytest.raises(RenderError, match=limit):
        image_framebuffer(ctx, (largest + 1, 1))
    image_framebuffer(ctx, (8, 8)).release()
