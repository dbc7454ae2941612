"""The plane homography's Gauss–Newton refinement and noise gain, compiled.

A frame's homography is refined on its ~60 marker corners in two or three steps,
and its noise gain takes two SVDs of the same Jacobian. In numpy these were ~40
small calls (Jacobians, products through BLAS, ``lstsq``, SVDs, an inverse) whose
overhead, not their arithmetic, was a fifth of a frame's registration. Here the
Jacobian is formed directly in the gauge basis, and LAPACK's least squares and
SVD (numba's bindings to the routines numpy calls) are reached from one compiled
call each. Cached on disk like the edge fits (:mod:`._edges`).

References
----------
.. [1] Hartley, Zisserman. *Multiple View Geometry*, 2nd ed., §5.2 (covariance of
   an estimated homography), §A6.2 (Gauss–Newton with a gauge constraint).
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["noise_gain", "refine_homography"]

_GN_ITERATIONS = 10


@njit(cache=True, nogil=True)
def refine_homography(H, plane, image):
    """Gauss–Newton on the image reprojection error, with ‖H‖ = 1 as a gauge.

    Parameters
    ----------
    H : (3, 3) float64
        The start, ‖H‖ = 1 (plate mm → undistorted pixels).
    plane, image : (n, 2) float64
        Plate points and their undistorted image positions.

    Returns
    -------
    (3, 3) float64
        The refined homography, ‖H‖ = 1.
    """
    # Steps orthogonal to the starting H (scaling H changes nothing): every homography
    # near it is reached that way, and the basis is computed once.
    basis = _gauge_basis(H)
    n = plane.shape[0]
    J = np.empty((2 * n, 8))
    residual = np.empty(2 * n)
    H = H.copy()
    for _ in range(_GN_ITERATIONS):
        _jacobian(H, plane, basis, J)
        for i in range(n):
            u, v = _project(H, plane[i, 0], plane[i, 1])
            residual[i] = image[i, 0] - u
            residual[n + i] = image[i, 1] - v
        step = np.linalg.lstsq(J, residual)[0]
        norm = 0.0
        for a in range(3):
            for b in range(3):
                for c in range(8):
                    H[a, b] += basis[3 * a + b, c] * step[c]
                norm += H[a, b] * H[a, b]
        H /= np.sqrt(norm)
        # Converged: a step of 1e-12 of the unit-norm H moves points by ~1e-9 px.
        if np.max(np.abs(step)) < 1e-12:
            break
    return H


@njit(cache=True, nogil=True)
def noise_gain(H, plane, sample_corners):
    """RMS image-position std at the ``sample_corners`` (k, 2) for unit noise on the
    image positions of the ``plane`` points (n, 2) of the fit H [1]_ §5.2; 1e12 for
    a degenerate fit."""
    basis = _gauge_basis(H)
    J = np.empty((2 * plane.shape[0], 8))
    _jacobian(H, plane, basis, J)
    singular = np.linalg.svd(J, full_matrices=False)[1]
    if singular[-1] <= 1e-10 * singular[0]:
        return 1e12
    cov = np.linalg.inv(J.T @ J)
    k = sample_corners.shape[0]
    Js = np.empty((2 * k, 8))
    _jacobian(H, sample_corners, basis, Js)
    variance = 0.0
    spread = np.empty(8)
    for i in range(2 * k):
        _times(Js[i], cov, spread)  # cov is symmetric: Js[i] @ cov = cov @ Js[i]
        variance += np.dot(Js[i], spread)
    return np.sqrt(variance / (2 * k) * 2.0)


@njit(cache=True, nogil=True)
def _gauge_basis(H):
    """(9, 8): an orthonormal basis of the entries' space orthogonal to H."""
    return np.ascontiguousarray(np.linalg.svd(H.reshape(1, 9).copy())[2][1:].T)


@njit(cache=True, nogil=True)
def _jacobian(H, plane, basis, J):
    """d(image point)/d(step in ``basis``) into J (2n, 8), rows u then v, for H acting
    on (x, y, 1)."""
    n = plane.shape[0]
    row = np.empty(9)
    for i in range(n):
        x, y = plane[i, 0], plane[i, 1]
        w = H[2, 0] * x + H[2, 1] * y + H[2, 2]
        u, v = _project(H, x, y)
        gx, gy, g1 = x / w, y / w, 1.0 / w
        row[0], row[1], row[2] = gx, gy, g1
        row[3] = row[4] = row[5] = 0.0
        row[6], row[7], row[8] = -u * gx, -u * gy, -u * g1
        _times(row, basis, J[i])
        row[0] = row[1] = row[2] = 0.0
        row[3], row[4], row[5] = gx, gy, g1
        row[6], row[7], row[8] = -v * gx, -v * gy, -v * g1
        _times(row, basis, J[n + i])


@njit(cache=True, nogil=True, inline="always")
def _times(row, matrix, out):
    """``out[:] = row @ matrix`` without a BLAS call per row."""
    for c in range(matrix.shape[1]):
        total = 0.0
        for k in range(matrix.shape[0]):
            total += row[k] * matrix[k, c]
        out[c] = total


@njit(cache=True, nogil=True, inline="always")
def _project(H, x, y):
    w = H[2, 0] * x + H[2, 1] * y + H[2, 2]
    return (H[0, 0] * x + H[0, 1] * y + H[0, 2]) / w, (H[1, 0] * x + H[1, 1] * y + H[1, 2]) / w
