"""Environment lighting: a compressed BTF on a mesh under an HDR environment map.

:class:`EnvironmentMap` and its readers (:mod:`render.environment.map`); per-vertex
visibility maps (:mod:`render.environment.visibility`, seed 003); the transfer of an
environment into per-vertex coefficients (``_transfer``) or through the PCA of
illumination (:mod:`render.environment.pca`); and :class:`EnvironmentRenderer`
(:mod:`render.environment.renderer`) that draws them.
"""

from render.environment.map import (
    SYNTHETIC_ENVIRONMENTS,
    EnvironmentMap,
    read_environment,
    synthetic_environment,
)
from render.environment.renderer import ENV_METHODS, EnvironmentRenderer

__all__ = [
    "ENV_METHODS",
    "SYNTHETIC_ENVIRONMENTS",
    "EnvironmentMap",
    "EnvironmentRenderer",
    "read_environment",
    "synthetic_environment",
]
