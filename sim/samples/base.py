"""Sample geometry and the registry of sample generators.

A *generator* turns validated parameters into the sample's surface as a
triangle mesh in the sample frame (mm), with exact vertex normals and a
material index per face. The holder (:mod:`sim.holder`) adds the plate, the
recess walls and the recess floor around it.

Height-field samples come with their height function ``z = h(x, y)``, so their
true normals and heights are analytic; other samples (the weave, later the
calibration targets) only need a mesh with normals.

New samples — calibration targets, for instance — register with
:func:`register_sample`::

    class MirrorParams(BaseModel):
        model_config = ConfigDict(extra="forbid", frozen=True)
        radius_mm: float = Field(10.0, gt=0)

    @register_sample("mirror_sphere", MirrorParams)
    def _mirror(params, *, sample_mm, depth_mm):
        return SampleGeometry(...)
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from pydantic import BaseModel

from rig.errors import ConfigError

__all__ = [
    "Generator",
    "SampleGeometry",
    "generator",
    "generator_names",
    "height_field_geometry",
    "height_normals",
    "register_sample",
]

HeightFn = Callable[[np.ndarray, np.ndarray], np.ndarray]


@dataclass(frozen=True)
class SampleGeometry:
    """The surface of one sample, sample frame.

    vertices : (V, 3) float64, mm (z ≤ 0)
    faces : (F, 3) int64
    normals : (V, 3) float64 unit vertex normals (exact surface normals there)
    face_material : (F,) int64 index into the generator's material list
    height : the height function ``h(x, y) -> z`` for height fields, else None
    pattern : for a printed target, ``points (n, 3) -> (n,)`` factors in [0, 1]
        that multiply the material's albedo (the print on it), else None
    """

    vertices: np.ndarray
    faces: np.ndarray
    normals: np.ndarray
    face_material: np.ndarray
    height: HeightFn | None = None
    pattern: Callable[[np.ndarray], np.ndarray] | None = None


@dataclass(frozen=True)
class Generator:
    """A registered sample generator.

    ``n_materials`` is how many material names the sample uses (e.g. the
    weave's warp and weft); ``build(params, sample_mm=, depth_mm=)`` returns a
    :class:`SampleGeometry`.
    """

    name: str
    params_model: type[BaseModel]
    build: Callable[..., SampleGeometry]
    n_materials: int = 1


_GENERATORS: dict[str, Generator] = {}


def register_sample(
    name: str, params_model: type[BaseModel], *, n_materials: int = 1
) -> Callable[[Callable[..., SampleGeometry]], Callable[..., SampleGeometry]]:
    """Decorator: register ``build`` as the generator ``name``."""

    def wrap(build: Callable[..., SampleGeometry]) -> Callable[..., SampleGeometry]:
        if name in _GENERATORS:
            raise ValueError(f"sample generator {name!r} is registered twice")
        _GENERATORS[name] = Generator(name, params_model, build, n_materials)
        return build

    return wrap


def generator_names() -> list[str]:
    """Names of all registered generators, sorted."""
    return sorted(_GENERATORS)


def generator(name: str) -> Generator:
    """The generator called ``name``; the error lists the valid names."""
    try:
        return _GENERATORS[name]
    except KeyError:
        raise ConfigError(
            f"unknown sample generator {name!r}; valid are {generator_names()}"
        ) from None


def height_field_geometry(
    height: HeightFn, *, sample_mm: float, grid: int, depth_mm: float, top_mm: float = 0.0
) -> SampleGeometry:
    """Triangulate ``z = h(x, y)`` over the sample square on a ``grid``² lattice.

    Normals come from central differences of ``h`` with a 1e-4 mm step (exact
    to ~1e-8 for smooth ``h``). Raises ``ConfigError`` when the surface leaves
    the recess (above z = ``top_mm`` or below the floor at −``depth_mm``); a
    sample stays below the reference plane (``top_mm`` 0), a calibration
    target may rise above it.
    """
    c = np.linspace(-sample_mm / 2, sample_mm / 2, grid)
    xx, yy = np.meshgrid(c, c)
    x, y = xx.ravel(), yy.ravel()
    z = height(x, y)
    top, bottom = float(z.max()), float(z.min())
    if top > top_mm + 1e-9 or bottom < -depth_mm - 1e-9:
        raise ConfigError(
            f"the sample surface spans z = {bottom:.3f} … {top:.3f} mm but must lie in the "
            f"recess, −{depth_mm} ≤ z ≤ {top_mm:g}: lower the amplitude or deepen depth_mm"
        )
    normals = height_normals(height, x, y)
    i = np.arange(grid * grid).reshape(grid, grid)
    a, b, cc, d = i[:-1, :-1].ravel(), i[:-1, 1:].ravel(), i[1:, 1:].ravel(), i[1:, :-1].ravel()
    faces = np.concatenate([np.stack([a, b, cc], 1), np.stack([a, cc, d], 1)])
    return SampleGeometry(
        vertices=np.column_stack([x, y, z]),
        faces=faces.astype(np.int64),
        normals=normals,
        face_material=np.zeros(len(faces), dtype=np.int64),
        height=height,
    )


def height_normals(height: HeightFn, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Unit normals (n, 3) of ``z = h(x, y)`` at points, by central differences."""
    eps = 1e-4
    hx = (height(x + eps, y) - height(x - eps, y)) / (2 * eps)
    hy = (height(x, y + eps) - height(x, y - eps)) / (2 * eps)
    n = np.column_stack([-hx, -hy, np.ones_like(hx)])
    return n / np.linalg.norm(n, axis=1, keepdims=True)
