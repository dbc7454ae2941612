"""Photometric stereo: normals, albedo and height of a sample from images under many lamps.

Solve one view with :func:`solve` (distant or near lamps, least squares or
robust), refine near-lamp solves with the integrated height
(:func:`refine_near`), integrate normals to a height map
(:func:`integrate_normals`: DCT Poisson, Frankot–Chellappa or masked sparse
least squares) and make preview images. Seed ``004`` (VirTex): Woodham's
photometric stereo, p/q gradients, Frankot–Chellappa integration.
"""

from ._errors import PhotometricError
from ._integrate import (
    INTEGRATORS,
    Gradients,
    HeightMap,
    gradients_from_normals,
    integrate_gradients,
    integrate_normals,
)
from ._lights import DistantLights, NearLights, PixelGrid, light_set_condition
from ._preview import albedo_preview, hillshade_preview, normal_map_preview
from ._refine import NearRefinement, refine_near
from ._result import CONDITION_CAP, PhotometricResult, Reason
from ._solve import DEFAULT_MAX_CONDITION, DEFAULT_METHOD, METHODS, solve

__all__ = [
    "CONDITION_CAP",
    "DEFAULT_MAX_CONDITION",
    "DEFAULT_METHOD",
    "INTEGRATORS",
    "METHODS",
    "DistantLights",
    "Gradients",
    "HeightMap",
    "NearLights",
    "NearRefinement",
    "PhotometricError",
    "PhotometricResult",
    "PixelGrid",
    "Reason",
    "albedo_preview",
    "gradients_from_normals",
    "hillshade_preview",
    "integrate_gradients",
    "integrate_normals",
    "light_set_condition",
    "normal_map_preview",
    "refine_near",
    "solve",
]
