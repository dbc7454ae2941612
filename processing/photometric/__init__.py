"""Photometric stereo: normals, albedo and height of a sample from images under many lamps."""

from ._errors import PhotometricError
from ._lights import DistantLights, NearLights, PixelGrid, light_set_condition
from ._result import CONDITION_CAP, PhotometricResult, Reason
from ._solve import DEFAULT_MAX_CONDITION, DEFAULT_METHOD, METHODS, solve

__all__ = [
    "CONDITION_CAP",
    "DEFAULT_MAX_CONDITION",
    "DEFAULT_METHOD",
    "METHODS",
    "DistantLights",
    "NearLights",
    "PhotometricError",
    "PhotometricResult",
    "PixelGrid",
    "Reason",
    "light_set_condition",
    "solve",
]
