"""Mesostructure silhouettes by depth peeling (``render.points.peel``) on the renderer's meshes."""

import dataclasses
import logging

import numpy as np
import pytest

from render import Camera, DirectionalLight, Renderer, RenderError
from render.meshes import plane, sphere, torus
from render.points.peel import MAX_PEEL, open_edges
from rig.material import Mdf
from tests.render.conftest import SAMPLE_MM, material, synthetic_mdf

LIGHT = [DirectionalLight((0.3, -0.5, 0.8))]
SIZE = (128, 96)


@pytest.fixture(scope="module")
def with_mdf(pca_model):
    return dataclasses.replace(material(pca_model), mdf=synthetic_mdf(n=16))


def torus_camera() -> Camera:
    return Camera.perspective((0, -260, 70), (0, 0, 0), fov_deg=30, size=SIZE)


def coverage(model, mesh, camera, **options) -> np.ndarray:
    with Renderer(model, mesh, shadows=False, **options) as renderer:
        return renderer.coverage(camera)


def test_mdf_trims_the_outline_and_never_adds_to_it(with_mdf):
    mesh = torus(segments=64)
    plain = coverage(with_mdf, mesh, torus_camera(), mdf=False)
    trimmed = coverage(with_mdf, mesh, torus_camera(), mdf=True, tile_mm=SAMPLE_MM)
    assert not np.any(trimmed & ~plain)
    # Depths up to 2 mm at 1.3 mm a pixel: the outline loses a pixel here and there.
    assert 0.005 < 1 - trimmed.sum() / plain.sum() < 0.1


def test_deeper_mesostructure_trims_more(with_mdf):
    mesh = torus(segments=64)
    trimmed = [coverage(with_mdf, mesh, torus_camera(), mdf=True, tile_mm=t) for t in (8, 40)]
    assert trimmed[1].sum() < trimmed[0].sum()


@pytest.mark.parametrize("passes", [1, 2, 3])
def test_torus_renders_finite_with_any_number_of_passes(with_mdf, passes):
    camera = torus_camera()
    with Renderer(with_mdf, torus(segments=64), mdf=True, peel=passes, tile_mm=20.0) as r:
        image = r.render(camera, LIGHT)
        rgba = np.frombuffer(r.draw(camera, LIGHT).read(components=4, dtype="f4"), np.float32)
        mask = r.coverage(camera)
    assert np.all(np.isfinite(image))
    assert mask.sum() > 1000
    # Shaded exactly where covered (alpha 1): the shading pass's depth test "==" draws
    # the faces the peel kept, each once, and nothing else.
    drawn = rgba.reshape(SIZE[1], SIZE[0], 4)[::-1, :, 3] > 0
    np.testing.assert_array_equal(drawn, mask)


def test_second_pass_recovers_the_far_side_behind_a_missed_near_side(with_mdf):
    """A ray that slips through the near tube's mesostructure hits the far tube (seen
    over the hole from low down): only a second layer finds it."""
    camera = Camera.perspective((0, -300, 45), (0, 0, 0), fov_deg=25, size=SIZE)
    one, two = (coverage(with_mdf, torus(segments=64), camera, mdf=True, peel=p, tile_mm=40.0)
                for p in (1, 2))  # fmt: skip
    assert not np.any(one & ~two)
    assert (two & ~one).sum() > 10


def test_all_unseen_mdf_keeps_the_mesh_outline(pca_model):
    blind = dataclasses.replace(material(pca_model), mdf=synthetic_mdf(n=16, unseen=1.0))
    mesh = sphere(segments=32)
    camera = Camera.perspective((0, -200, 60), (0, 0, 0), fov_deg=40, size=SIZE)
    np.testing.assert_array_equal(
        coverage(blind, mesh, camera, mdf=True), coverage(blind, mesh, camera, mdf=False)
    )


def test_open_mesh_is_drawn_without_silhouettes_and_warns(with_mdf, caplog):
    mesh = plane(size_mm=60.0, segments=4)
    camera = Camera.perspective((0, -120, 40), (0, 0, 0), fov_deg=40, size=SIZE)
    with (
        caplog.at_level(logging.WARNING, logger="render.points.peel"),
        Renderer(with_mdf, mesh, mdf=True) as renderer,
    ):
        assert renderer.silhouettes is None
        mask = renderer.coverage(camera)
    assert "is open (16 edges bound one face only)" in caplog.text
    np.testing.assert_array_equal(mask, coverage(with_mdf, mesh, camera, mdf=False))


def test_open_edges_counts_holes_not_uv_seams():
    assert open_edges(torus()) == 0
    assert open_edges(sphere()) == 0
    assert open_edges(plane(segments=2)) == 8


def test_mdf_requested_without_one_names_the_material(pca_model):
    with pytest.raises(RenderError, match=r"'test-material' holds no mdf.*--no-mdf"):
        Renderer(material(pca_model), torus(), mdf=True)


def test_default_uses_the_mdf_when_the_material_holds_one(with_mdf, pca_model):
    with Renderer(with_mdf, torus(segments=16)) as renderer:
        assert renderer.silhouettes is not None
    with Renderer(material(pca_model), torus(segments=16)) as renderer:
        assert renderer.silhouettes is None


@pytest.mark.parametrize("passes", [0, MAX_PEEL + 1, 1.5])
def test_bad_pass_counts_are_refused(with_mdf, passes):
    with pytest.raises(RenderError, match=f"peel = {passes}: valid are 1…{MAX_PEEL}"):
        Renderer(with_mdf, torus(segments=16), peel=passes)


def test_texture_scale_follows_tile_mm(with_mdf):
    with Renderer(with_mdf, torus(segments=16), tile_mm=2 * SAMPLE_MM) as renderer:
        program = renderer.silhouettes.programs[1][0]
        assert program["texture_scale"].value == pytest.approx(2.0)


def test_constant_mdf_shrinks_a_sphere_to_the_analytic_outline(pca_model):
    """D = d everywhere: a ray through a sphere of radius R at distance ρ from its centre
    crosses a chord 2√(R² − ρ²), so it meets the mesostructure where ρ ≤ √(R² − d²)."""
    radius, depth, n, width = 50.0, 30.0, 128, 120.0
    views = pca_model.view_dirs_deg
    shape = (len(views), 8, 8)
    constant = Mdf(np.full(shape, depth, np.float32), views.astype(np.float32),
                   np.zeros(shape, np.uint8), np.ones(shape, np.uint8))  # fmt: skip
    model = dataclasses.replace(material(pca_model), mdf=constant)
    camera = Camera.orthographic((0, -200, 0), (0, 0, 0), up=(0, 0, 1), height=width, size=(n, n))
    mask = coverage(model, sphere(radius_mm=radius, segments=96), camera, mdf=True)
    centres = (np.arange(n) + 0.5) / n * width - width / 2
    rho = np.hypot(*np.meshgrid(centres, centres[::-1]))
    expected = rho <= np.sqrt(radius**2 - depth**2)
    pixel = width / n
    unsure = np.abs(rho - np.sqrt(radius**2 - depth**2)) < 1.5 * pixel
    np.testing.assert_array_equal(mask[~unsure], expected[~unsure])
    assert abs(np.sqrt(mask.sum() / np.pi) * pixel - 40.0) < pixel


def test_open_mesh_with_the_mdf_not_asked_for_only_informs(with_mdf, caplog):
    """The MDF that merely came with the material: an open mesh is no warning (an info line)."""
    with (
        caplog.at_level(logging.INFO, logger="render.points.peel"),
        Renderer(with_mdf, plane(size_mm=60.0, segments=4)) as renderer,
    ):
        assert renderer.silhouettes is None
    [record] = [r for r in caplog.records if "is open" in r.getMessage()]
    assert record.levelno == logging.INFO
