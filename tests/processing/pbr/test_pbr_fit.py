"""The PBR fit recovers known glTF parameters from a BTF the specification's formulas
generate (``gltf_reference``, independent of the code under test), and stays finite
and flagged in the hard cases."""

import functools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from numpy.testing import assert_allclose

from processing.pbr import FitOptions, PbrError, PbrFlag, fit_texels
from rig.geometry import direction_vector
from tests.processing.pbr.gltf_reference import radiance, sheen_e

VIEWS = [(0, 0), *[(40, p) for p in range(0, 360, 90)], *[(65, p) for p in range(45, 360, 90)]]
LIGHTS = [(0, 0), *[(30, p) for p in range(0, 360, 60)], *[(60, p) for p in range(30, 360, 60)],
          *[(80, p) for p in range(0, 360, 45)]]  # fmt: skip
NAMES = ("base_colour", "roughness", "specular", "specular_colour", "sheen_colour",
         "sheen_roughness", "anisotropy", "anisotropy_deg", "normal")  # fmt: skip


@functools.cache
def _e_grid():
    mus, rs = np.linspace(0, 1, 11), np.linspace(0.07, 1, 8)
    return mus, rs, np.array([[sheen_e(mu, r, order=24) for r in rs] for mu in mus])


def _e(mu, r):
    mus, rs, grid = _e_grid()
    column = [np.interp(mu, mus, grid[:, j]) for j in range(len(rs))]
    return float(np.interp(r, rs, column))


def _pairs(views, lights):
    v = direction_vector(*np.array(views, float).T)
    lt = direction_vector(*np.array(lights, float).T)
    return np.tile(lt, (len(v), 1)), np.repeat(v, len(lt), axis=0)


def _texels(rng, count, **fixed):
    normal = np.c_[rng.normal(0, 0.15, (count, 2)), np.ones(count)]
    texels = {
        "base_colour": rng.uniform(0.1, 0.8, (count, 3)),
        "roughness": rng.uniform(0.25, 0.7, count),
        "specular": rng.uniform(0.5, 1, count), "specular_colour": rng.uniform(1, 4, count),
        "sheen_colour": rng.uniform(0, 0.3, (count, 3)),
        "sheen_roughness": rng.uniform(0.3, 0.8, count),
        "anisotropy": rng.uniform(0, 0.7, count), "anisotropy_deg": rng.uniform(0, 180, count),
        "normal": normal / np.linalg.norm(normal, axis=1, keepdims=True),
    }  # fmt: skip
    texels.update({k: np.broadcast_to(v, np.shape(texels[k])).copy() for k, v in fixed.items()})
    return texels


def _btf(texels, light, view):
    count = len(texels["roughness"])
    return np.array([[radiance({k: texels[k][i] for k in NAMES}, light[m], view[m], e_table=_e)
                      for m in range(len(light))] for i in range(count)])  # fmt: skip


def test_recovers_the_parameters_that_made_the_btf():
    rng = np.random.default_rng(7)
    texels = _texels(rng, 24)
    light, view = _pairs(VIEWS, LIGHTS)
    fit = fit_texels(_btf(texels, light, view), light, view)
    p = fit.params

    def p90(name):
        return np.percentile(np.abs(getattr(p, name) - texels[name]), 90)

    assert p90("base_colour") < 0.01
    assert p90("roughness") < 0.02
    assert p90("specular") < 0.05
    assert p90("sheen_colour") < 0.02
    assert p90("sheen_roughness") < 0.05
    assert p90("anisotropy") < 0.03
    strong = texels["anisotropy"] > 0.3
    turn = (p.anisotropy_deg - texels["anisotropy_deg"] + 90) % 180 - 90
    assert np.percentile(np.abs(turn[strong]), 90) < 2.0
    angle = np.degrees(np.arccos(np.clip(np.sum(p.normal * texels["normal"], 1), -1, 1)))
    assert np.percentile(angle, 90) < 0.5
    assert np.median(fit.error_rmse) < 2e-3
    assert not np.any(fit.flags & (PbrFlag.DARK | PbrFlag.NO_SPECULAR))


def test_outliers_count_little():
    rng = np.random.default_rng(11)
    texels = _texels(rng, 12, anisotropy=0.0, sheen_colour=0.0)
    light, view = _pairs(VIEWS, LIGHTS)
    btf = _btf(texels, light, view)
    dust = rng.random(btf.shape[:2]) < 0.05
    btf[dust] *= 4.0
    fit = fit_texels(btf, light, view)
    assert np.percentile(np.abs(fit.params.base_colour - texels["base_colour"]), 90) < 0.02


def test_black_texels_stay_finite_and_flagged():
    light, view = _pairs(VIEWS, LIGHTS)
    fit = fit_texels(np.zeros((3, len(light), 3)), light, view)
    for name in NAMES:
        assert np.all(np.isfinite(getattr(fit.params, name)))
    assert np.all(fit.flags & PbrFlag.DARK)
    assert_allclose(fit.params.base_colour, 0.0)
    assert_allclose(fit.params.roughness, FitOptions().roughness_prior)


def test_clipped_samples_are_left_out_and_flagged():
    rng = np.random.default_rng(5)
    texels = _texels(rng, 8, anisotropy=0.0, roughness=0.3)
    light, view = _pairs(VIEWS, LIGHTS)
    btf = _btf(texels, light, view)
    level = np.percentile(btf, 97)
    fit = fit_texels(np.minimum(btf, level), light, view, options=FitOptions(saturation=level))
    assert np.all(fit.flags & PbrFlag.SATURATED)
    assert np.percentile(np.abs(fit.params.base_colour - texels["base_colour"]), 90) < 0.03
    assert np.all(np.isfinite(fit.error_rmse))


def test_without_specular_signal_roughness_stays_at_its_prior():
    rng = np.random.default_rng(2)
    texels = _texels(rng, 6, specular=0.0, sheen_colour=0.0, anisotropy=0.0)
    light, view = _pairs(VIEWS, LIGHTS)
    options = FitOptions(roughness_prior=0.45)
    fit = fit_texels(_btf(texels, light, view), light, view, options=options)
    assert np.all(fit.flags & PbrFlag.NO_SPECULAR)
    assert_allclose(fit.params.roughness, 0.45, atol=0.05)
    assert_allclose(fit.params.base_colour, texels["base_colour"], atol=0.01)


@pytest.mark.parametrize(
    ("lights", "expected"),
    [([(30, 40)], PbrFlag.SINGLE_LIGHT | PbrFlag.NORMAL_UNFIT),
     ([(45, p) for p in range(0, 360, 45)], PbrFlag.ONE_ELEVATION)],
    ids=["single light", "one elevation"],
)  # fmt: skip
def test_poor_light_sets_stay_finite_and_flagged(lights, expected):
    rng = np.random.default_rng(4)
    texels = _texels(rng, 4, anisotropy=0.0)
    light, view = _pairs(VIEWS, lights)
    start = np.tile([0.0, 0.0, 1.0], (4, 1))
    fit = fit_texels(_btf(texels, light, view), light, view, normal_init=start)
    assert np.all(fit.flags & expected == expected)
    for name in NAMES:
        assert np.all(np.isfinite(getattr(fit.params, name)))
    if expected & PbrFlag.NORMAL_UNFIT:
        assert_allclose(fit.params.normal, start, atol=1e-6)


@settings(max_examples=10, deadline=None)
@given(
    values=arrays(np.float64, (3, 6, 3), elements=st.one_of(
        st.floats(0, 1e4), st.just(0.0), st.just(np.inf), st.just(np.nan))),
    thetas=st.lists(st.floats(0, 89), min_size=1, max_size=6),
)  # fmt: skip
def test_any_samples_give_finite_flagged_maps(values, thetas):
    lights = [(theta, 60.0 * i) for i, theta in enumerate(thetas)]
    light, view = _pairs([(0, 0)], lights)
    samples = np.resize(values, (3, len(light), 3))
    fit = fit_texels(samples, light, view, options=FitOptions(iterations=4))
    for name in NAMES:
        assert np.all(np.isfinite(getattr(fit.params, name)))
    assert np.all(np.isfinite(fit.error_rmse))
    assert np.all(fit.flags < 64)
    assert np.all((fit.params.roughness >= 0.03) & (fit.params.roughness <= 1))


def test_arrays_that_do_not_fit_together_are_named():
    light, view = _pairs(VIEWS, LIGHTS)
    samples = np.zeros((2, len(light), 3))
    with pytest.raises(PbrError, match=r"view: shape \(3, 3\); expected \(189, 3\)"):
        fit_texels(samples, light, view[:3])
    with pytest.raises(PbrError, match=r"normal_init: shape \(1, 3\); expected \(2, 3\)"):
        fit_texels(samples, light, view, normal_init=np.zeros((1, 3)))
