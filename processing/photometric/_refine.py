"""Near-lamp photometric stereo refined by the integrated height.

Near lamps light each pixel from a direction and distance that depend on
where the surface is; the first solve assumes the pixels lie on z = 0. Each
iteration integrates the normals to a height map and solves again with the
pixels lifted to that height.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._errors import PhotometricError
from ._integrate import HeightMap, integrate_normals
from ._lights import NearLights, PixelGrid
from ._result import PhotometricResult
from ._solve import solve


@dataclass(frozen=True)
class NearRefinement:
    """The last solve, the height map integrated from it, and the re-solves done."""

    result: PhotometricResult
    height: HeightMap
    iterations: int


def refine_near(
    images: np.ndarray,
    lights: NearLights,
    *,
    grid: PixelGrid,
    iterations: int = 2,
    integrator: str = "dct",
    flat_beyond_mm: float | None = None,
    **solve_options,
) -> NearRefinement:
    """Solve with near lamps, then alternate integrate → re-solve ``iterations`` times.

    Parameters
    ----------
    images : (L, H, W) or (L, H, W, 3) array
        As for :func:`solve`.
    lights : NearLights
    grid : PixelGrid
        Where the pixels lie on the sample plane; heights are added to it.
    iterations : int
        Re-solves after the first (0: one solve and one integration).
    integrator : {"dct", "fc", "lsq", "auto"}
        Passed to :func:`integrate_normals` over the full grid (invalid
        pixels hold the flat normal, so they integrate as flat).
    flat_beyond_mm : float, optional
        Passed to :func:`integrate_normals`: the heights the re-solves lift the
        pixels to, and the one returned, have no shape longer than it.
    **solve_options
        Keyword options of :func:`solve` (``method``, ``max_condition``…).
    """
    if not isinstance(lights, NearLights):
        raise PhotometricError(f"lights: refine_near needs NearLights, got {type(lights).__name__}")
    if not isinstance(grid, PixelGrid):
        raise PhotometricError(f"grid: expected a PixelGrid, got {type(grid).__name__}")
    if int(iterations) != iterations or iterations < 0:
        raise PhotometricError(f"iterations: expected an integer ≥ 0, got {iterations!r}")
    if "pixels" in solve_options:
        raise PhotometricError("pixels: refine_near sets the pixel positions from grid; drop it")
    height_mm = None
    for _ in range(int(iterations) + 1):
        result = solve(images, lights, pixels=grid.positions_mm(height_mm), **solve_options)
        height = integrate_normals(
            result.normals, pitch_mm=grid.pitch_mm, method=integrator,
            flat_beyond_mm=flat_beyond_mm,
        )  # fmt: skip
        height_mm = height.height_mm.astype(np.float64)
    return NearRefinement(result, height, int(iterations))
