"""Mesostructure-aware shadows and the ambient term in the renderer (seed 001 §4.2).

The shadow boundaries themselves are checked against the ray-cast truth in
``tests/studies/test_mdf_shadows.py``; here: the ambient term on the GPU
against its numpy reference, the shadow maps' push to the mesostructure's
base and its grazing clamp, and the hard cases.
"""

import dataclasses

import numpy as np
import pytest

from render import Camera, DirectionalLight, Renderer, RenderError
from render.core.gl import gl_context, mesh_buffers
from render.meshes import merged, plane, sphere
from render.points._shadows import ShadowMaps, light_camera
from render.points.ambient import ambient_term
from render.points.mdf import GRAZING_DEG
from render.texel_view import texel_camera
from rig.geometry import direction_vector, nearest_directions
from rig.material import Mdf
from tests.render.conftest import SAMPLE_MM, VIEWS, N, material, tilted_quad
from tests.render.test_mdf import synthetic_mdf


def with_mdf(model, mdf: Mdf):
    return dataclasses.replace(material(model), mdf=mdf)


def test_a_surface_facing_away_from_the_light_is_unlit_not_shadowed(pca_model):
    """Below the horizon a light brings nothing, so its shadow holds nothing back: no
    ambient term. Counted as all held back it lit the night side of a sphere with the
    ambient term while the lit side faded to black at the terminator: a hard-edged
    crescent at the rim."""
    mesh, frame = tilted_quad((23.0, 41.0))
    below = DirectionalLight(tuple(frame @ np.array([0.3, 0.2, -0.93])), intensity=2.0)
    with Renderer(with_mdf(pca_model, synthetic_mdf()), mesh, mdf=True, ambient=0.5) as r:
        assert np.all(r.render(texel_camera(SAMPLE_MM, N), [below]) == 0)


def ball_over_floor():
    ball = sphere(radius_mm=6.0, segments=16)
    ball = dataclasses.replace(ball, positions=ball.positions + np.float32([0, 0, 10]))
    return merged([plane(size_mm=40.0, segments=4), ball], name="ball over floor")


def render_scene(model, mdf, light_deg, *, use_mdf, camera_deg=(30.0, 200.0)):
    camera = Camera.orthographic(direction_vector(*camera_deg) * 100, (0, 0, 0), height=44.0,
                                 size=(96, 96))  # fmt: skip
    light = DirectionalLight(tuple(direction_vector(*light_deg)))
    with Renderer(with_mdf(model, mdf), ball_over_floor(), mdf=use_mdf, ambient=0.0,
                  tile_mm=10.0, shadow_size=256) as renderer:  # fmt: skip
        return renderer.render(camera, [light])


@pytest.mark.parametrize("kind", ["pca", "svd"])
@pytest.mark.parametrize("view_deg", [(0.0, 0.0), (23.0, 41.0), (64.0, 137.0)])
def test_a_cast_shadow_shows_the_ambient_term_of_what_it_holds_back(kind, view_deg, request):
    """A texel-exact quad in the shadow of a roof, a light at θ_l = 40° in the quad's frame
    (from opposite the view): the shadow holds back E cos θ_l, so each texel shows
    a · E cos θ_l / π · Σ_j ω_j L_a,j, the view slots blended as the BTF blends them. The
    roof, twice the quad's side (the view pulls the shadow test's point along the view ray by up
    to the MDF's depth), floats 2 sides above the quad along the light
    ray, out of the camera's frame, which holds the quad alone."""
    model = request.getfixturevalue(f"{kind}_model")
    quad, frame = tilted_quad(view_deg)
    light_local = direction_vector(40.0, view_deg[1] + 180.0)
    roof = plane(size_mm=2.0 * SAMPLE_MM, segments=1)
    lifted = roof.positions + 2.0 * SAMPLE_MM * light_local / light_local[2]
    roof = dataclasses.replace(
        roof, positions=(lifted @ frame.T).astype(np.float32),
        normals=(roof.normals @ frame.T).astype(np.float32),
        tangents=np.concatenate([roof.tangents[:, :3] @ frame.T, roof.tangents[:, 3:]], axis=1)
        .astype(np.float32),
    )  # fmt: skip
    light = DirectionalLight(tuple(frame @ light_local), intensity=2.0)
    scene = merged([quad, roof], name="quad under a roof")
    with Renderer(with_mdf(model, synthetic_mdf()), scene, mdf=True, ambient=0.5) as renderer:
        image = renderer.render(texel_camera(SAMPLE_MM, N), [light])
    blend = nearest_directions(direction_vector(VIEWS[:, 0], VIEWS[:, 1]),
                               direction_vector(*view_deg), k=4)  # fmt: skip
    slots = np.tensordot(blend.weights[0], ambient_term(model)[blend.indices[0]], axes=1)
    expected = 0.5 * 2.0 * light_local[2] / np.pi * slots
    assert np.abs(expected).max() > 0.01
    np.testing.assert_allclose(image, expected, atol=1e-4 * np.abs(expected).max())


def test_an_mdf_that_is_all_unseen_changes_nothing(pca_model):
    """No texel seen: d_max = 0 and D = 0 everywhere, so shadows are the mesh's own."""
    mdf = synthetic_mdf(unseen=1.0)
    assert np.all(mdf.distance_mm == -1)
    with_it = render_scene(pca_model, mdf, (40.0, 10.0), use_mdf=True)
    without = render_scene(pca_model, mdf, (40.0, 10.0), use_mdf=False)
    assert np.all(np.isfinite(with_it))
    np.testing.assert_allclose(with_it, without, atol=1e-6)


@pytest.mark.parametrize(("light_deg", "camera_deg"), [((89.5, 10.0), (30.0, 200.0)),
                                                       ((45.0, 10.0), (89.0, 200.0))])  # fmt: skip
def test_grazing_light_and_view_stay_finite(pca_model, light_deg, camera_deg):
    image = render_scene(pca_model, synthetic_mdf(), light_deg, use_mdf=True,
                         camera_deg=camera_deg)  # fmt: skip
    assert np.all(np.isfinite(image))
    assert image.max() > 0


def shadow_depth_mm(light, base_depth: float) -> float:
    """Distance from the light to the floor's centre that its shadow map holds, mm."""
    ctx = gl_context()
    floor = plane(size_mm=40.0, segments=2)
    vbo, ibo = mesh_buffers(ctx, floor)
    maps = ShadowMaps(ctx, vbo, ibo, size=64, base_depth=base_depth)
    try:
        center, radius = np.zeros(3), 20.0
        maps.draw([light], center, radius)
        depth = np.frombuffer(maps.atlas.read(), np.float32).reshape(64, 64)[32, 32]
        near, far = light_camera(light, center, radius, 64).depth_range(center, radius)
        return near + float(depth) * (far - near)  # orthographic: depth is linear
    finally:
        maps.release()
        vbo.release()
        ibo.release()


@pytest.mark.parametrize("theta", [0.0, 60.0, 85.0])
def test_shadow_maps_hold_the_mesostructure_base(theta):
    """z + d / cos θ_l along the light ray, with cos θ_l held at cos 80° for grazing light."""
    light = DirectionalLight(tuple(direction_vector(theta, 30.0)))
    push = shadow_depth_mm(light, 1.5) - shadow_depth_mm(light, 0.0)
    slant = 1 / max(np.cos(np.radians(theta)), np.cos(np.radians(GRAZING_DEG)))
    np.testing.assert_allclose(push, 1.5 * slant, rtol=1e-3)


def test_mdf_options_are_checked(pca_model):
    mesh, _ = tilted_quad((0.0, 0.0))
    with pytest.raises(RenderError, match=r"holds no mdf.*--no-mdf"):
        Renderer(material(pca_model), mesh, mdf=True)
    for bad in (-0.1, 1.5, float("nan")):
        with pytest.raises(RenderError, match=f"ambient = {bad}: valid is a fraction"):
            Renderer(with_mdf(pca_model, synthetic_mdf()), mesh, mdf=True, ambient=bad)
