"""Inputs at the edge of what the renderer can see: every output pixel finite.

Grazing views (θ → 90°), light from behind the surface, degenerate triangles
and zero-area UVs, empty view slots, HDR texels up to 6e4.
"""

import dataclasses

import numpy as np
import pytest

from processing.btf import interpolate
from render import Camera, DirectionalLight, PointLight, Renderer
from render.lights import MAX_EMISSION
from render.meshes import Mesh, sphere
from rig.geometry import direction_vector
from rig.material import CompressedBTF
from tests.render.conftest import material, ps_view, tilted_quad
from tests.render.test_exact import FLOAT16_EPS, render_at


@pytest.mark.parametrize("kind", ["pca", "svd"])
@pytest.mark.parametrize("view_deg", [(89.0, 30.0), (90.0, 200.0)])
def test_grazing_views_are_finite_and_match_the_horizon(kind, view_deg, request):
    model = request.getfixturevalue(f"{kind}_model")
    image = render_at(material(model), view_deg, (30.0, 10.0))
    assert np.isfinite(image).all()
    expected = interpolate(model, view_deg=view_deg, light_deg=(30.0, 10.0))
    np.testing.assert_allclose(image, expected, atol=FLOAT16_EPS * np.abs(expected).max())


@pytest.mark.parametrize("layers", [("btf",), ("ps",), ("btf", "ps")])
def test_light_behind_the_surface_gives_black(pca_model, layers):
    m = material(pca_model, ps=ps_view())
    image = render_at(m, (20.0, 0.0), (120.0, 45.0), layers=layers, specular=0.5)
    assert np.array_equal(image, np.zeros_like(image))


def test_silhouettes_of_a_sphere_are_finite(pca_model):
    """Interpolated normals turn away from the eye at the rim: views below the horizon."""
    camera = Camera.perspective((0, -120, 40), (0, 0, 0), fov_deg=40, size=(96, 96))
    lights = [PointLight((60, -60, 80), intensity=2e4), DirectionalLight((0, 1, 0.1))]
    with Renderer(material(pca_model, ps=ps_view()), sphere(radius_mm=30, segments=6)) as r:
        image = r.render(camera, lights)
    assert np.isfinite(image).all()
    assert (image.sum(axis=2) > 0).mean() > 0.2  # the sphere is there and lit


def test_degenerate_triangles_and_zero_area_uvs_are_finite(pca_model):
    positions = np.array(
        [[-10, -10, 0], [10, -10, 0], [10, 10, 0], [-10, 10, 0], [0, 0, 0], [0, 0, 0]], np.float32
    )
    uvs = np.array([[0, 0], [20, 0], [20, 20], [0, 20], [5, 5], [5, 5]], np.float32)
    uvs[:3] = 7.0  # the first triangle has no UV area
    normals = np.tile([0, 0, 1], (6, 1)).astype(np.float32)
    normals[4] = 0.0  # a vertex without a normal
    tangents = np.tile([1, 0, 0, 1], (6, 1)).astype(np.float32)
    tangents[5] = [0, 0, 1, 1]  # a tangent along the normal
    faces = np.array([[0, 1, 2], [0, 2, 3], [4, 4, 5], [0, 4, 5], [3, 5, 2]], np.uint32)
    mesh = Mesh(positions=positions, normals=normals, uvs=uvs, tangents=tangents, faces=faces,
                name="degenerate")  # fmt: skip
    camera = Camera.perspective((5, -30, 40), (0, 0, 0), size=(64, 64))
    with Renderer(material(pca_model, ps=ps_view()), mesh, specular=0.3) as renderer:
        image = renderer.render(camera, [PointLight((0, 0, 30), intensity=900.0)])
    assert np.isfinite(image).all()
    assert image.max() > 0


def test_empty_view_slots_are_skipped(pca_model):
    """Empty slots hold HDR garbage; the render equals the blend over the valid slots."""
    view_deg = tuple(pca_model.view_dirs_deg[7])
    valid = np.ones(len(pca_model.view_dirs_deg), bool)
    valid[[7, 8, 11]] = False  # the slot at the view direction and two neighbours
    mean = pca_model.mean.copy()
    mean[~valid] = 6e4
    stored = dataclasses.replace(pca_model, mean=mean)
    for method in ("nearest4", "barycentric"):
        image = render_at(material(stored, slot_valid=valid), view_deg, (34.0, 30.0),
                          view_method=method, light_method=method)  # fmt: skip
        kept = CompressedBTF(
            pca_model.view_dirs_deg[valid], pca_model.light_dirs_deg, pca_model.mean[valid],
            pca_model.basis[valid], pca_model.weights[valid], pca_model.singular_values[valid],
            pca_model.rank[valid],
        )  # fmt: skip
        expected = interpolate(kept, view_deg=view_deg, light_deg=(34.0, 30.0),
                               view_method=method, light_method=method)  # fmt: skip
        np.testing.assert_allclose(image, expected, atol=FLOAT16_EPS * np.abs(expected).max())


def test_lamps_touching_the_surface_at_the_largest_emission_stay_finite(pca_model):
    mesh, _ = tilted_quad((0.0, 0.0))
    # 0.1 µm above pixel centres (r² below the 1 µm² floor), and one on the surface.
    lamps = [PointLight((x, 0.625, 1e-4), intensity=MAX_EMISSION) for x in (-4.375, 0.625)]
    lamps.append(PointLight((5.0, 5.0, 0.0), intensity=MAX_EMISSION))
    camera = Camera.orthographic((0, 0, 100), (0, 0, 0), up=(0, 1, 0), height=20.0, size=(16, 16))
    with Renderer(material(pca_model, ps=ps_view()), mesh, specular=1.0) as renderer:
        image = renderer.render(camera, lamps)
    assert np.isfinite(image).all()
    assert image.max() > 1e24


def test_hdr_texels_up_to_6e4(pca_model):
    """Mean texels scaled to 6e4 (near float16's 65504), four bright lights: finite and exact."""
    scale = 6e4 / np.abs(pca_model.mean.astype(np.float32)).max()
    hdr = dataclasses.replace(
        pca_model, mean=(pca_model.mean.astype(np.float32) * scale).astype(np.float16),
        weights=pca_model.weights * scale,
    )  # fmt: skip
    assert np.abs(hdr.mean.astype(np.float32)).max() > 5.9e4
    mesh, frame = tilted_quad((10.0, 0.0))
    directions = [(0.0, 0.0), (30.0, 90.0), (60.0, 200.0), (80.0, 300.0)]
    lights = [DirectionalLight(tuple(frame @ direction_vector(*d)), intensity=1e3)
              for d in directions]  # fmt: skip
    camera = Camera.orthographic((0, 0, 100), (0, 0, 0), up=(0, 1, 0), height=20.0, size=(16, 16))
    with Renderer(material(hdr), mesh) as renderer:
        image = renderer.render(camera, lights)
    assert np.isfinite(image).all()
    expected = sum(1e3 * interpolate(hdr, view_deg=(10.0, 0.0), light_deg=d) for d in directions)
    np.testing.assert_allclose(image, expected, rtol=0, atol=FLOAT16_EPS * np.abs(expected).max())
