"""The CPU glTF model against the specification's formulas written out independently."""

import numpy as np
import pytest
from numpy.testing import assert_allclose

from processing.pbr import PbrParams, evaluate, sheen_albedo
from rig.geometry import direction_vector
from tests.processing.pbr.gltf_reference import radiance, sheen_e


def _params(rng, count):
    normal = np.c_[rng.normal(0, 0.25, (count, 2)), np.ones(count)]
    return PbrParams(
        base_colour=rng.uniform(0, 1, (count, 3)), roughness=rng.uniform(0.1, 1, count),
        specular=rng.uniform(0, 1, count), specular_colour=rng.uniform(0, 5, count),
        sheen_colour=rng.uniform(0, 0.6, (count, 3)), sheen_roughness=rng.uniform(0.1, 1, count),
        anisotropy=rng.uniform(0, 1, count), anisotropy_deg=rng.uniform(0, 180, count),
        normal=normal / np.linalg.norm(normal, axis=1, keepdims=True),
    )  # fmt: skip


def test_sheen_albedo_matches_a_quadrature_of_the_lobe():
    for mu, r in [(0.15, 0.2), (0.5, 0.5), (0.9, 0.9), (1.0, 0.3)]:
        assert sheen_albedo(mu, r) == pytest.approx(sheen_e(mu, r), abs=0.01)


def test_evaluate_matches_the_specification_per_pair():
    rng = np.random.default_rng(3)
    params = _params(rng, 6)
    light = direction_vector(rng.uniform(0, 85, 7), rng.uniform(0, 360, 7))
    view = direction_vector(rng.uniform(0, 85, 7), rng.uniform(0, 360, 7))
    got = evaluate(params, light, view)
    e = sheen_albedo  # the table is checked above; the lobe and layering are checked here
    for i in range(6):
        texel = {k: getattr(params, k)[i] for k in params.__dataclass_fields__}
        for j in range(7):
            want = radiance(texel, light[j], view[j], e_table=e)
            assert_allclose(got[i, j], want, rtol=1e-6, atol=1e-9)


def test_a_white_diffuse_texel_lit_frontally_reads_one():
    flat = PbrParams(np.ones((1, 3)), np.array([0.5]), np.zeros(1), np.ones(1),
                     np.zeros((1, 3)), np.array([0.5]), np.zeros(1), np.zeros(1),
                     np.array([[0.0, 0.0, 1.0]]))  # fmt: skip
    frontal = np.array([[0.0, 0.0, 1.0]])
    assert_allclose(evaluate(flat, frontal, direction_vector(30.0, 0.0)[None]), 1.0, rtol=1e-12)


def test_below_the_tangent_plane_is_black_and_finite():
    params = _params(np.random.default_rng(1), 3)
    grazing = direction_vector(np.array([90.0, 89.999]), np.array([0.0, 180.0]))
    out = evaluate(params, grazing, grazing[::-1])
    assert np.all(np.isfinite(out)) and np.all(out >= 0)
