"""A glTF PBR material fitted to the measured BTF (``rig process --stages pbr``).

:func:`evaluate` is the model — glTF 2.0 metallic-roughness (metallic 0) with
KHR_materials_specular, KHR_materials_sheen and KHR_materials_anisotropy — on the
CPU; :func:`fit_texels` fits it to each texel's measured (light, view) samples with a
robust loss in linear radiance; :func:`btf_samples` gives those samples for a strip
of texel rows of a compressed BTF. The maps are stored through
``rig.material.write_pbr`` (``docs/interchange.md`` shows the fit's error).
"""

from processing.pbr._brdf import (
    SHEEN_ROUGHNESS_MIN,
    PbrParams,
    anisotropy_frame,
    evaluate,
    sheen_albedo,
)
from processing.pbr._fit import FitOptions, PbrFitResult, fit_texels
from processing.pbr._samples import btf_samples
from rig.material import PbrFlag

__all__ = [
    "SHEEN_ROUGHNESS_MIN",
    "FitOptions",
    "PbrFitResult",
    "PbrFlag",
    "PbrParams",
    "anisotropy_frame",
    "btf_samples",
    "evaluate",
    "fit_texels",
    "sheen_albedo",
]
