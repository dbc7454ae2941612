"""The plane homography's fit (DLT and Gauss–Newton) and noise gain, compiled.

A frame's homography is fitted to its ~60 marker corners, and its noise gain
takes two SVDs of the same Jacobian. As OpenCV's ``findHomography`` (DLT and
Levenberg–Marquardt on float32 points) followed by Gauss–Newton steps in numpy,
~40 small calls (Jacobians, products through BLAS, ``lstsq``, SVDs, an inverse)
whose overhead, not their arithmetic, was a fifth of a frame's registration.
Here the DLT, the Gauss–Newton steps (the Jacobian formed directly in the gauge
basis) and the noise gain are one compiled call each. LAPACK's reduced SVD is the
only routine they reach (through numba): the null vector, the least-squares steps
and the covariance all come from it, which keeps the first compile at ~9 s (~15 s
with ``lstsq``, ``eigh`` and ``inv`` besides). From the DLT the steps reach the same
minimum as from OpenCV's start (to 1e-15 of the unit-norm H on the default scene's
frames). Cached on disk like the edge fits (:mod:`._edges`).

References
----------
.. [1] Hartley, Zisserman. *Multiple View Geometry*, 2nd ed., §5.2 (covariance of
   an estimated homography), §A6.2 (Gauss–Newton with a gauge constraint).
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["fit_homography", "noise_gain", "refine_homography"]

_GN_ITERATIONS = 10


@njit(cache=True, nogil=True)
def fit_homography(plane, image):
    """The plane → image homography (3, 3), ‖H‖ = 1, of least squared image reprojection
    error: the normalised DLT [1]_ §4.4 refined by :func:`refine_homography`.

    ``plane``, ``image`` : (n, 2) float64, n ≥ 4. Points too degenerate for a DLT
    (coincident, non-finite) give the identity, which the caller's checks flag.
    """
    to_plane, ok_plane = _normaliser(plane)
    to_image, ok_image = _normaliser(image)
    if not (ok_plane and ok_image):
        return np.eye(3)
    n = plane.shape[0]
    A = np.zeros((max(2 * n, 9), 9))
    for i in range(n):
        px = to_plane[0, 0] * plane[i, 0] + to_plane[0, 2]
        py = to_plane[1, 1] * plane[i, 1] + to_plane[1, 2]
        ix = to_image[0, 0] * image[i, 0] + to_image[0, 2]
        iy = to_image[1, 1] * image[i, 1] + to_image[1, 2]
        A[i, 0], A[i, 1], A[i, 2] = px, py, 1.0
        A[i, 6], A[i, 7], A[i, 8] = -ix * px, -ix * py, -ix
        A[n + i, 3], A[n + i, 4], A[n + i, 5] = px, py, 1.0
        A[n + i, 6], A[n + i, 7], A[n + i, 8] = -iy * px, -iy * py, -iy
    # The null vector of A: its last right singular vector (rows of zeros added up to
    # nine leave it unchanged and give the reduced SVD its ninth vector).
    h = np.linalg.svd(A, False)[2][8].copy().reshape(3, 3)
    H = _times3(_times3(_inverse_similarity(to_image), h), to_plane)
    norm = np.sqrt(np.sum(H * H))
    if not (norm > 0 and np.isfinite(norm)):
        return np.eye(3)
    if H[2, 2] < 0:  # the singular vector's sign is arbitrary; OpenCV's DLT had H[2, 2] = 1
        norm = -norm
    return refine_homography(H / norm, plane, image)


@njit(cache=True, nogil=True)
def _normaliser(points):
    """(3, 3) similarity taking ``points`` (n, 2) to centroid 0, mean distance √2; and
    whether it exists (distinct, finite points)."""
    n = points.shape[0]
    cx, cy = points[:, 0].mean(), points[:, 1].mean()
    spread = 0.0
    for i in range(n):
        spread += np.hypot(points[i, 0] - cx, points[i, 1] - cy)
    T = np.eye(3)
    if not (spread > 0 and np.isfinite(spread)):
        return T, False
    scale = np.sqrt(2.0) * n / spread
    T[0, 0] = T[1, 1] = scale
    T[0, 2], T[1, 2] = -scale * cx, -scale * cy
    return T, True


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
        step = _least_squares(J, residual)
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
    _, singular, vt = np.linalg.svd(J, False)
    if singular[-1] <= 1e-10 * singular[0]:
        return 1e12
    k = sample_corners.shape[0]
    Js = np.empty((2 * k, 8))
    _jacobian(H, sample_corners, basis, Js)
    # (JᵀJ)⁻¹ = V S⁻² Vᵀ: a row's variance j (JᵀJ)⁻¹ jᵀ = ‖S⁻¹ Vᵀ jᵀ‖².
    variance = 0.0
    for i in range(2 * k):
        for a in range(8):
            along = 0.0
            for b in range(8):
                along += vt[a, b] * Js[i, b]
            variance += (along / singular[a]) ** 2
    return np.sqrt(variance / (2 * k) * 2.0)


@njit(cache=True, nogil=True)
def _gauge_basis(H):
    """(9, 8): an orthonormal basis of the entries' space orthogonal to H: the columns but
    one of the Householder reflection taking H's direction to a coordinate axis."""
    h = H.ravel() / np.sqrt(np.sum(H * H))
    k = np.argmax(np.abs(h))
    v = h.copy()
    v[k] += 1.0 if h[k] >= 0 else -1.0
    scale = 2.0 / np.sum(v * v)
    basis = np.empty((9, 8))
    for a in range(9):
        column = 0
        for b in range(9):
            if b != k:
                basis[a, column] = (1.0 if a == b else 0.0) - scale * v[a] * v[b]
                column += 1
    return basis


@njit(cache=True, nogil=True)
def _least_squares(J, r):
    """The least-squares step x minimising ‖J x − r‖ (``np.linalg.lstsq(J, r)``: singular
    values below ε · max(J's shape) · the largest dropped), by the reduced SVD."""
    u, singular, vt = np.linalg.svd(J, False)
    cutoff = 2.220446049250313e-16 * max(J.shape[0], J.shape[1]) * singular[0]
    x = np.zeros(J.shape[1])
    for a in range(len(singular)):
        if singular[a] <= cutoff:
            continue
        along = 0.0
        for i in range(J.shape[0]):
            along += u[i, a] * r[i]
        along /= singular[a]
        for b in range(J.shape[1]):
            x[b] += vt[a, b] * along
    return x


@njit(cache=True, nogil=True)
def _inverse_similarity(T):
    """The inverse of a similarity ``[[s, 0, tx], [0, s, ty], [0, 0, 1]]`` (:func:`_normaliser`)."""
    inverse = np.eye(3)
    inverse[0, 0] = inverse[1, 1] = 1.0 / T[0, 0]
    inverse[0, 2], inverse[1, 2] = -T[0, 2] / T[0, 0], -T[1, 2] / T[1, 1]
    return inverse


@njit(cache=True, nogil=True)
def _times3(a, b):
    """``a @ b`` of two (3, 3) matrices, without BLAS."""
    out = np.zeros((3, 3))
    for i in range(3):
        for j in range(3):
            for k in range(3):
                out[i, j] += a[i, k] * b[k, j]
    return out


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
