"""The ambient term L_a (seed 001 §4.2) against direct sums over the measured lights."""

import numpy as np
import pytest

from processing.btf import interpolate
from render.core.hemisphere import hemicube
from render.points.ambient import ambient_term, light_solid_angles
from rig.geometry import Sampling, direction_vector
from rig.material import CompressedBTF
from tests.render.conftest import LIGHTS, VIEWS, N


@pytest.mark.parametrize("method", ["nearest4", "barycentric", "nearest"])
def test_light_weights_integrate_the_cosine_of_a_lambertian_plane(method):
    """Textures holding cos θ_i of their light (a Lambertian plane) sum with the weights
    to the hemisphere's cosine integral, π: the blends carry the light's cosine."""
    vectors = direction_vector(LIGHTS[:, 0], LIGHTS[:, 1])
    w = light_solid_angles(vectors, light_method=method)
    assert w.shape == (len(LIGHTS),)
    assert np.all(w >= 0)
    directions, solid_angles = hemicube(64)
    np.testing.assert_allclose(w @ vectors[:, 2], solid_angles @ directions[:, 2], rtol=1e-12)
    np.testing.assert_allclose(w @ vectors[:, 2], np.pi, rtol=1e-4)  # the quadrature's own error


@pytest.mark.parametrize("kind", ["pca", "svd"])
def test_ambient_is_the_weighted_sum_of_every_measured_light(kind, request):
    """Per slot, the collapsed PCA/SVD sum equals Σ_i w_i T(v, l_i) of the reconstructed images."""
    model = request.getfixturevalue(f"{kind}_model")
    ambient = ambient_term(model)
    w = light_solid_angles(model.light_vectors)
    assert ambient.shape == (len(VIEWS), N, N, model.reconstruct_view(0).shape[-1])
    assert ambient.dtype == np.float32
    for slot in (0, 7, 20):
        images = model.reconstruct_view(slot).astype(np.float64)  # (n_lights, N, N, C)
        direct = np.tensordot(w, images, axes=1)
        tolerance = 1e-5 * np.abs(direct).max()
        np.testing.assert_allclose(ambient[slot], direct, rtol=1e-5, atol=tolerance)


def test_ambient_follows_the_renderers_light_interpolation(pca_model):
    """Midpoint rule over many directional lights, each blended as the renderer blends it."""
    rng = np.random.default_rng(3)
    dirs = rng.normal(size=(4000, 3))
    dirs[:, 2] = np.abs(dirs[:, 2])
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    theta = np.degrees(np.arccos(dirs[:, 2]))
    phi = np.degrees(np.arctan2(dirs[:, 1], dirs[:, 0])) % 360
    view = tuple(VIEWS[4])
    samples = [
        interpolate(pca_model, view_deg=view, light_deg=light)
        for light in zip(theta, phi, strict=True)
    ]
    mc = np.mean(samples, axis=0) * 2 * np.pi  # uniform over the hemisphere: mean × 2π sr
    ambient = ambient_term(pca_model)[4]
    # Monte Carlo with 4000 directions: ~1.6 % per texel of the integrand's spread.
    np.testing.assert_allclose(ambient, mc, rtol=0, atol=0.03 * np.abs(mc).max())


def test_lambertian_texels_give_their_albedo():
    """T = ρ/π · cos θ_l (a white lamp's normtexture of a Lambertian texel) integrates to ρ,
    above the highest measured ring (θ_top = 75°) too: the blend carries the light's
    cosine to the horizon (held at the top ring's value instead, ρ cos² θ_top = 6.7 % more)."""
    rng = np.random.default_rng(0)
    albedo = rng.uniform(0.2, 0.9, (1, 1, N, N, 3)).astype(np.float32)
    lights = Sampling.named("H2").directions  # rings up to θ_top = 75°
    n_views, n_lights = len(VIEWS), len(lights)
    cos_l = np.cos(np.radians(lights[:, 0]))
    btf = CompressedBTF(
        VIEWS, lights, np.zeros((n_views, N, N, 3), np.float32),
        np.repeat(albedo / np.pi, n_views, axis=0),
        np.broadcast_to(cos_l[None, :, None], (n_views, n_lights, 1)).astype(np.float32),
        np.ones((n_views, n_lights), np.float32), np.ones(n_views, np.int32),
    )  # fmt: skip
    ambient = ambient_term(btf, light_method="barycentric")
    # The hemicube's quadrature of cos θ is 8e-5 off π; the texture is float32.
    np.testing.assert_allclose(ambient, np.broadcast_to(albedo[0], ambient.shape), rtol=2e-4)
