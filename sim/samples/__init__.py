"""Sample generators: height fields, the weave, calibration targets, and a registry."""

from sim.samples import heightfields, sphere, targets, weave
from sim.samples.base import (
    Generator,
    SampleGeometry,
    generator,
    generator_names,
    height_field_geometry,
    height_normals,
    register_sample,
)

__all__ = [
    "Generator",
    "SampleGeometry",
    "generator",
    "generator_names",
    "height_field_geometry",
    "height_normals",
    "heightfields",
    "register_sample",
    "sphere",
    "targets",
    "weave",
]
