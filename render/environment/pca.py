"""PCA of illumination: the environment's coefficients for any rotation (seed 000 §5.4).

The coefficient vector U of an environment (:mod:`render.environment._transfer`)
changes slowly as the environment turns about the vertical axis. U is computed
for A rotations δ_a = a · 360°/A; their first e eigen-weight-sets W_k (the
right singular vectors of the A × D matrix, uncentred, as the seed) give
U_a ≈ Σ_k o_ak W_k with o_ak = U_a · W_k (eq. (13)). A rotation between two
samples blends their weights o linearly, so turning the environment costs e
scaled sums of length D instead of a new pass over every visibility map.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from render._errors import RenderError
from render.environment._transfer import environment_coefficients

__all__ = ["IlluminationBasis", "check_basis_size", "illumination_basis"]


@dataclass(frozen=True)
class IlluminationBasis:
    """e eigen-weight-sets of A rotations of one environment.

    Attributes
    ----------
    eigen_sets : (e, D) float32
        W_k, unit rows; D = V · n_views · (c + 1) · 3 (a global SVD: V · n_lights · 3).
    weights : (A, e) float64
        o_ak of each sampled rotation.
    shape : tuple
        U's shape, (V, n_views, c + 1, 3) or (V, n_lights, 1, 3).
    energy : float
        Fraction of Σ |U_a|² the e sets keep (1 = exact at the samples).
    seconds : float
        Time to compute the A coefficient vectors and their PCA.
    """

    eigen_sets: np.ndarray
    weights: np.ndarray
    shape: tuple
    energy: float
    seconds: float

    @property
    def rotations(self) -> int:
        return len(self.weights)

    def coefficients(self, rotation_deg: float) -> np.ndarray:
        """U at ``rotation_deg`` (the sampled weights blended linearly): shape :attr:`shape`."""
        if not np.isfinite(rotation_deg):
            raise RenderError(f"rotation_deg = {rotation_deg}: must be finite")
        position = (rotation_deg % 360.0) / 360.0 * self.rotations
        below = int(np.floor(position)) % self.rotations
        above = (below + 1) % self.rotations
        frac = position - np.floor(position)
        o = (1.0 - frac) * self.weights[below] + frac * self.weights[above]
        return (o.astype(np.float32) @ self.eigen_sets).reshape(self.shape)


def check_basis_size(rotations, components) -> None:
    """A RenderError unless 2 ≤ ``rotations`` and 1 ≤ ``components`` ≤ ``rotations`` (ints)."""
    if not (isinstance(rotations, int) and rotations >= 2):
        raise RenderError(f"rotations = {rotations!r}: need an int ≥ 2")
    if not (isinstance(components, int) and 1 <= components <= rotations):
        raise RenderError(f"components = {components!r}: need an int in [1, rotations={rotations}]")


def illumination_basis(
    maps, environment, btf, *, rotations: int = 30, components: int = 5
) -> IlluminationBasis:
    """Sample ``rotations`` turns of ``environment`` and keep ``components`` eigen-weight-sets.

    Seed 000 uses A = 30 rotations of 12° and e = 5. The environment's own
    rotation is the origin the samples turn from.
    """
    check_basis_size(rotations, components)
    started = time.perf_counter()
    turns = environment.rotation_deg + np.arange(rotations) * 360.0 / rotations
    samples = [
        environment_coefficients(maps, environment.with_view(rotation_deg=float(turn)), btf)
        for turn in turns
    ]
    shape = samples[0].shape
    stack = np.stack([u.reshape(-1) for u in samples])  # (A, D) float32
    del samples
    # The A × A Gram matrix instead of an SVD of the A × D stack: D is large, A small.
    gram = stack.astype(np.float64) @ stack.T.astype(np.float64)
    values, vectors = np.linalg.eigh(gram)
    order = np.argsort(values)[::-1]
    values, vectors = np.clip(values[order], 0.0, None), vectors[:, order]
    keep = values[:components] > values[0] * 1e-12 if values[0] > 0 else np.zeros(components, bool)
    kept = int(keep.sum()) or 1
    sigma = np.sqrt(np.maximum(values[:kept], 1e-300))
    eigen_sets = ((vectors[:, :kept].T @ stack.astype(np.float64)) / sigma[:, None]).astype(
        np.float32
    )
    if values[0] <= 0:  # an all-black environment: U is zero at every rotation
        eigen_sets = np.zeros((1, stack.shape[1]), np.float32)
    weights = stack.astype(np.float64) @ eigen_sets.T.astype(np.float64)
    total = float(values.sum())
    energy = float(values[:kept].sum() / total) if total > 0 else 1.0
    return IlluminationBasis(
        eigen_sets=eigen_sets, weights=weights, shape=shape, energy=energy,
        seconds=time.perf_counter() - started,
    )  # fmt: skip
