"""The renderer's pbr layer: each pixel of a texel-aligned view is the CPU model
(``rig.material.evaluate_pbr``) at its texel; it draws alone and only when asked."""

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from render import Renderer, RenderError
from rig.geometry import direction_vector
from rig.material import Material, PbrParams, evaluate_pbr
from tests.render.conftest import SAMPLE_MM, N, tilted_quad
from tests.render.test_exact import render_at
from tests.rig.material.conftest import pbr_maps

NAMES = ("base_colour", "roughness", "specular", "specular_colour", "sheen_colour",
         "sheen_roughness", "anisotropy", "anisotropy_deg", "normal")  # fmt: skip


def _material(maps, btf=None) -> Material:
    return Material(
        source=Path("test-material"), sample_mm=SAMPLE_MM, size=N, pbr=maps, btf=btf,
        btf_slot_valid=None if btf is None else np.ones(len(btf.view_dirs_deg), bool),
    )  # fmt: skip


@pytest.mark.parametrize(
    ("view_deg", "light_deg"), [((0.0, 0.0), (30.0, 45.0)), ((41.0, 250.0), (63.0, 17.0))]
)
def test_each_pixel_is_the_cpu_model_at_its_texel(view_deg, light_deg):
    maps = pbr_maps(n=N)
    maps = dataclasses.replace(maps, attrs={"white": 1.7})
    image = render_at(_material(maps), view_deg, light_deg)
    params = PbrParams(**{k: getattr(maps, k).reshape(N * N, -1).squeeze(-1)
                          if getattr(maps, k).ndim == 2 else getattr(maps, k).reshape(N * N, -1)
                          for k in NAMES})  # fmt: skip
    light = direction_vector(*light_deg)[None]
    view = direction_vector(*view_deg)[None]
    expected = 1.7 * evaluate_pbr(params, light, view)[:, 0].reshape(N, N, 3)
    np.testing.assert_allclose(image, expected, rtol=2e-3, atol=1e-4 * expected.max())


def test_the_fit_draws_alone_and_only_when_asked(pca_model):
    material = _material(pbr_maps(n=N), btf=pca_model)
    quad, _ = tilted_quad((0.0, 0.0))
    with pytest.raises(RenderError, match="the PBR fit stands for the BTF and the PS maps"):
        Renderer(material, quad, layers=("btf", "pbr"))
    with Renderer(material, quad) as renderer:
        assert renderer.layers == ("btf",)
