"""Per-vertex hemicube visibility maps cast against the mesh itself."""

import numpy as np
import pytest

from render import RenderError
from render.core.hemisphere import hemicube
from render.environment.visibility import visibility_maps
from render.meshes import Mesh, plane, sphere
from rig.geometry import Sampling, nearest_directions

LIGHTS = Sampling.named("H1").vectors


@pytest.mark.parametrize("resolution", [2, 8, 32])
def test_hemicube_texels_cover_the_hemisphere_exactly(resolution):
    directions, solid = hemicube(resolution)
    assert directions.shape == (3 * resolution**2, 3)
    np.testing.assert_allclose(solid.sum(), 2 * np.pi, rtol=1e-12)
    assert directions[:, 2].min() > 0
    # Texel solid angles against the centre approximation dA / |p|³ (finer: closer).
    if resolution == 32:
        area = (2 / resolution) ** 2
        p = directions / np.max(np.abs(directions), axis=1, keepdims=True)
        np.testing.assert_allclose(solid, area / np.linalg.norm(p, axis=1) ** 3, rtol=2e-3)


def test_open_plane_sees_its_whole_hemisphere():
    maps = visibility_maps(plane(segments=2), LIGHTS, resolution=4)
    assert maps.visibility().all()


def test_inside_of_a_sphere_sees_nothing():
    ball = sphere(radius_mm=20.0, segments=12)
    inside = Mesh(
        positions=ball.positions, normals=-ball.normals, uvs=ball.uvs, tangents=ball.tangents,
        faces=ball.faces, name="inside of a ball",
    )  # fmt: skip
    assert not visibility_maps(inside, LIGHTS, resolution=4).visibility().any()
    assert visibility_maps(ball, LIGHTS, resolution=4).visibility().all()


def test_texel_light_table_is_rig_geometry_nearest_four():
    maps = visibility_maps(plane(), LIGHTS, resolution=6)
    expected = nearest_directions(LIGHTS, maps.directions, k=4)
    np.testing.assert_array_equal(maps.light_indices, expected.indices)
    # Shepard's weights carrying the cosine: a texture of cos θ_i blends to the texel's cos θ.
    cos_i = LIGHTS[maps.light_indices, 2] / np.linalg.norm(LIGHTS, axis=1)[maps.light_indices]
    cos_q = np.maximum(maps.directions[:, 2], 0.0)
    np.testing.assert_allclose(maps.light_weights / cos_q[:, None] * cos_i, expected.weights)
    np.testing.assert_allclose(np.sum(maps.light_weights * cos_i, axis=1), cos_q, atol=1e-12)
    bary = visibility_maps(plane(), LIGHTS, resolution=6, light_method="barycentric")
    assert bary.light_indices.shape == (maps.texels, 3)


def test_bad_resolution_and_method_are_named():
    with pytest.raises(RenderError, match="even int"):
        hemicube(5)
    with pytest.raises(RenderError, match="light_method"):
        visibility_maps(plane(), LIGHTS, light_method="bilinear")
