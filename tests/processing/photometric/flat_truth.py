"""The simulator's ray-cast truth of a flat sample on the texel grid, and how much shape
longer than its mesostructure a height map has (docs/photometric.md, "A flat sample")."""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from sim import Simulator

#: "Low frequency": a Gaussian of this many texels (6.25 mm on a 100 mm sample at 128²).
LOW_SIGMA_TEXELS = 8


def texel_truth_over_footprints(scene, n: int, supersample: int = 4):
    """Ray-cast normals at the n² texel centres (n, n, 3), the ray-cast height (mm)
    averaged over each texel's footprint from supersample² rays (n, n), and the texel
    pitch (mm). The centres' normals are what a texel-sampled normal map holds: they
    never show the yarns' sides (averaged over the footprint, they would)."""
    with Simulator(scene) as sim:
        normals = sim.texel_truth(n, rays=1).normals
        height = sim.texel_truth(n, rays=supersample).height.astype(np.float64)
        pitch_mm = sim.scene.rig.holder.sample_mm / n
    return normals, height, pitch_mm


def less_plane(height) -> np.ndarray:
    """A height map less its least-squares plane (a flat sample's reference plane)."""
    rows, cols = np.indices(height.shape)
    basis = np.column_stack([cols.ravel(), rows.ravel(), np.ones(height.size)])
    plane, *_ = np.linalg.lstsq(basis, np.asarray(height, np.float64).ravel(), rcond=None)
    return height - (basis @ plane).reshape(height.shape)


def low_frequency_std(height) -> float:
    """Std (mm) of the low-frequency part of a height map less its plane."""
    return float(ndimage.gaussian_filter(less_plane(height), LOW_SIGMA_TEXELS).std())
