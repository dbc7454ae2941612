"""Macro shadows: a ball above a floor casts a shadow with a soft edge and no acne."""

import dataclasses

import numpy as np
import pytest

from render import Camera, DirectionalLight, PointLight, Renderer
from render.meshes import Mesh, merged, plane, sphere
from tests.render.conftest import material, ps_view

PIXELS = 128  # over 160 mm: 1.25 mm per pixel
FLOOR_MM = 160.0


def ball_over_floor() -> Mesh:
    floor, ball = plane(size_mm=FLOOR_MM), sphere(radius_mm=15.0, segments=16)
    ball = dataclasses.replace(ball, positions=ball.positions + np.float32([0.0, 0.0, 30.0]))
    return merged([floor, ball], name="ball over floor")


@pytest.fixture(scope="module")
def flat_grey():
    ps = ps_view()
    flat = np.zeros_like(ps.normals)
    flat[..., 2] = 1.0
    return material(ps=dataclasses.replace(ps, normals=flat, albedo=np.full_like(ps.albedo, 0.5)))


def row_through_centre(flat_grey, light, *, shadows, shadow_size=128) -> np.ndarray:
    camera = Camera.orthographic((0, 0, 200), (0, 0, 0), up=(0, 1, 0), height=FLOOR_MM,
                                 size=(PIXELS, PIXELS))  # fmt: skip
    with Renderer(flat_grey, ball_over_floor(), shadows=shadows, shadow_size=shadow_size) as r:
        image = r.render(camera, [light])
    assert np.isfinite(image).all()
    return image[PIXELS // 2, :, 0]


@pytest.mark.parametrize(
    "light", [DirectionalLight((1.0, 0.0, 1.0)), PointLight((200.0, 0.0, 200.0), intensity=8e4)]
)
def test_ball_shadows_the_floor_with_a_soft_edge(flat_grey, light):
    lit = row_through_centre(flat_grey, light, shadows=False)
    shadowed = row_through_centre(flat_grey, light, shadows=True)
    x_mm = (np.arange(PIXELS) + 0.5) * FLOOR_MM / PIXELS - FLOOR_MM / 2
    # Away from the shadow the floor is lit as without shadows: no self-shadowing acne.
    np.testing.assert_allclose(shadowed[x_mm > 20], lit[x_mm > 20], rtol=1e-5)
    # From the floor's far left edge towards the ball (height 30 mm, light from 45°,
    # shadow centred near x = −30…−35 mm): lit, a soft edge falling over several
    # pixels, then the umbra.
    left = (x_mm > -78) & (x_mm < -25)
    ratio = shadowed[left] / lit[left]
    assert ratio[0] > 0.999
    assert ratio[-1] < 0.01
    assert np.all(np.diff(ratio) <= 1e-4)
    assert np.count_nonzero((ratio > 0.05) & (ratio < 0.95)) >= 3
