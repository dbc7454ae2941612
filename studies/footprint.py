"""The footprint truth a comparison has converged on: as many rays per texel as it needs.

A texel is an area, so its truth is the noise-free BTF averaged over its
footprint (``Simulator.btf_truth(…, rays=k)``: k × k rays per texel). How many
rays are enough depends on what the truth is compared with: a comparison is
converged when doubling k changes its PSNR by less than a tolerance. The
render-loop and error-budget benches score with :func:`converged_truth`, and
say which k they reached.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from processing.btf import psnr_db, rmse
from sim.simulator import Simulator

__all__ = ["FootprintTruth", "converged_truth"]


@dataclass(frozen=True)
class FootprintTruth:
    """A footprint truth and how far it converged.

    values : (pairs, n, n, 3) float32, 1/sr — the truth at ``rays`` per texel side
    rays : rays per texel side of ``values``
    change_db : |PSNR(k) − PSNR(k/2)| of the comparison, dB, at the last doubling
    converged : ``change_db`` is below the tolerance (False: ``most`` was reached first)
    """

    values: np.ndarray
    rays: int
    change_db: float
    converged: bool


def truth_at(sim: Simulator, pairs, size: int, rays: int) -> np.ndarray:
    """(pairs, size, size, 3) float32: the footprint truth at (view, light) pairs."""
    return np.stack([sim.btf_truth(view, light, size, rays=rays) for view, light in pairs])


def converged_truth(
    sim: Simulator,
    pairs,
    measured: np.ndarray,
    *,
    peak: float | None = None,
    start: int = 4,
    most: int = 32,
    tol_db: float = 0.1,
) -> FootprintTruth:
    """Double the rays per texel side from ``start`` until the PSNR of ``measured``
    against the truth changes by less than ``tol_db``.

    Parameters
    ----------
    sim : the simulator of the sample
    pairs : sequence of ((θ, φ) view, (θ, φ) light) degrees, sample frame
    measured : (pairs, n, n, 3) what is scored, in ``btf_truth`` units
    peak : the PSNR's peak; None: the truth's maximum at each k
    start, most : first and largest rays per side (most ≥ 2 · start)
    tol_db : the convergence tolerance, dB

    Returns
    -------
    FootprintTruth at the first k whose PSNR is within ``tol_db`` of k/2's;
    at ``most`` with ``converged`` False when none is.
    """
    if not (start >= 1 and 2 * start <= most) or tol_db <= 0:
        raise ValueError(
            f"start={start}, most={most}, tol_db={tol_db}: need 1 ≤ start, 2 · start ≤ most "
            "and tol_db > 0"
        )
    size = measured.shape[1]

    def score(truth):
        return psnr_db(rmse(measured, truth), peak=float(truth.max()) if peak is None else peak)

    rays, truth = start, truth_at(sim, pairs, size, start)
    last = score(truth)
    while 2 * rays <= most:
        rays *= 2
        truth = truth_at(sim, pairs, size, rays)
        now = score(truth)
        change, last = abs(now - last), now
        if change < tol_db:
            return FootprintTruth(truth, rays, change, True)
    return FootprintTruth(truth, rays, change, False)
