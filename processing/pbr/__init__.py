"""A glTF PBR material fitted to the measured BTF (``rig process --stages pbr``).

:func:`evaluate` is the model — glTF 2.0 metallic-roughness (metallic 0) with
KHR_materials_specular, KHR_materials_sheen and KHR_materials_anisotropy — on the
CPU (the material format's ``rig.material.evaluate_pbr``, re-exported here);
:func:`fit_texels` fits it to each texel's measured (light, view) samples with a
robust loss in linear radiance; :func:`btf_samples` gives those samples for a strip
of texel rows of a compressed BTF. The maps are stored through
``rig.material.write_pbr`` (``docs/interchange.md`` shows the fit's error).
"""

from processing.pbr._errors import PbrError
from processing.pbr._fit import FitOptions, PbrFitResult, fit_texels
from processing.pbr._samples import btf_samples
from rig.material import (
    SHEEN_ROUGHNESS_MIN,
    PbrFlag,
    PbrParams,
    anisotropy_frame,
    evaluate_terms,
    sheen_albedo,
)
from rig.material import evaluate_pbr as evaluate

__all__ = [
    "SHEEN_ROUGHNESS_MIN",
    "FitOptions",
    "PbrError",
    "PbrFitResult",
    "PbrFlag",
    "PbrParams",
    "anisotropy_frame",
    "btf_samples",
    "evaluate",
    "evaluate_terms",
    "fit_texels",
    "sheen_albedo",
]
