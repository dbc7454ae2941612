"""Height from normals: surface gradients and three integrators.

Sign convention: the surface is z = h(x, y) in the sample frame (z up), so its
normal is proportional to (-∂h/∂x, -∂h/∂y, 1) and the gradients are
``p = ∂h/∂x = -n_x / n_z`` and ``q = ∂h/∂y = -n_y / n_z``. Images have rows
along -y and columns along +x (row 0 at +y, see
:func:`rig.geometry.texel_centers_mm`), so per pixel ``h[r, c+1] - h[r, c] ≈
p · pitch`` and ``h[r+1, c] - h[r, c] ≈ -q · pitch``.

Heights are in mm. The constant of integration is fixed like the rig's
reference plane: the highest valid point of each connected region is z = 0.

A flat sample (the rig's: it lies on the holder plate) has no shape longer
than its mesostructure, but its normals, sampled per texel, cannot show the
cliffs of a textile (yarn sides, the floor seen through gaps), and what those
cliffs' missing heights add to the gradients' divergence integrates into
shape at the beat of the weave with the texel grid (``docs/photometric.md``).
``flat_beyond_mm`` removes the best-fit plane and every wavelength longer than
it from the height: a high-pass of order 4 in the DCT domain,
``1 / (1 + (λ / flat_beyond_mm)^8)`` of a wavelength λ kept (half of it at
the cutoff, 99.6 % at half the cutoff).

References
----------
.. [1] Frankot, R. T., Chellappa, R. "A method for enforcing integrability in
   shape from shading algorithms." IEEE PAMI 10(4), 1988 (seed ``004``).
.. [2] Simchony, T., Chellappa, R., Shao, M. "Direct analytical methods for
   solving Poisson equations in computer vision problems." IEEE PAMI 12(5),
   1990 (the DCT solver).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.fft
import scipy.sparse
import scipy.sparse.csgraph
import scipy.sparse.linalg

from ._errors import PhotometricError
from ._inputs import check_positive

INTEGRATORS = ("dct", "fc", "lsq")


@dataclass(frozen=True)
class Gradients:
    """Surface slopes per pixel.

    Attributes
    ----------
    p, q : (H, W) float64
        ∂h/∂x and ∂h/∂y (dimensionless); 0 where the normal was invalid.
    clipped : (H, W) bool
        Where the slope exceeded ``max_slope_deg`` (n_z ≈ 0 or negative) and
        was clipped to it, keeping its direction.
    """

    p: np.ndarray
    q: np.ndarray
    clipped: np.ndarray


@dataclass(frozen=True)
class HeightMap:
    """An integrated height map.

    Attributes
    ----------
    height_mm : (H, W) float32
        Surface height in mm; max over each valid region is 0; 0 where invalid.
    valid : (H, W) bool
        Pixels that were integrated.
    slope_clipped : (H, W) bool
        Pixels whose slope was clipped before integration.
    method : str
        The integrator used: "dct", "fc" or "lsq".
    """

    height_mm: np.ndarray
    valid: np.ndarray
    slope_clipped: np.ndarray
    method: str


def gradients_from_normals(normals, *, valid=None, max_slope_deg: float = 80.0) -> Gradients:
    """Gradients p = -n_x/n_z, q = -n_y/n_z of unit normals, clipped to a maximum slope.

    Parameters
    ----------
    normals : (H, W, 3) float array
        Normals in the sample frame.
    valid : (H, W) bool, optional
        Pixels to use; others get p = q = 0.
    max_slope_deg : float
        Largest slope angle kept (0 < value < 90); steeper normals, including
        n_z ≤ 0, are clipped to it and flagged.
    """
    n = np.asarray(normals, dtype=np.float64)
    if n.ndim != 3 or n.shape[2] != 3:
        raise PhotometricError(f"normals: expected shape (H, W, 3), got {n.shape}")
    if not 0 < max_slope_deg < 90:
        raise PhotometricError(f"max_slope_deg: expected 0 < value < 90, got {max_slope_deg!r}")
    use = _check_mask(valid, n.shape[:2], "valid")
    use = use & np.all(np.isfinite(n), axis=2)
    limit = np.tan(np.deg2rad(max_slope_deg))
    nx, ny, nz = (np.where(use, n[..., i], 0.0) for i in range(3))
    lateral = np.hypot(nx, ny)
    steep = use & (lateral > limit * nz)  # includes n_z ≤ 0 with any tilt
    flat_down = use & (lateral == 0) & (nz <= 0)  # (0, 0, -1): no direction to keep
    safe_nz = np.where(steep | ~use | flat_down, 1.0, nz)
    safe_lat = np.where(lateral > 0, lateral, 1.0)
    p = np.where(steep, -limit * nx / safe_lat, -nx / safe_nz)
    q = np.where(steep, -limit * ny / safe_lat, -ny / safe_nz)
    zero = ~use | flat_down
    return Gradients(np.where(zero, 0.0, p), np.where(zero, 0.0, q), steep | flat_down)


def integrate_gradients(
    p, q, *, pitch_mm: float, mask=None, method: str = "auto", flat_beyond_mm: float | None = None
) -> HeightMap:
    """Integrate surface gradients to a height map in mm.

    Parameters
    ----------
    p, q : (H, W) float arrays
        ∂h/∂x and ∂h/∂y, see the module docstring for the sign convention.
    pitch_mm : float
        Pixel spacing on the sample, mm.
    mask : (H, W) bool, optional
        Pixels to integrate. "dct" and "fc" treat gradients outside it as 0;
        "lsq" uses only equations between neighbouring masked pixels.
    method : {"auto", "dct", "fc", "lsq"}
        "auto": "dct" for a full rectangle, "lsq" for an irregular mask.
        "dct": least squares with Neumann boundaries by a DCT Poisson solve.
        "fc": Frankot–Chellappa, periodic boundaries, by FFT.
        "lsq": sparse least squares over the mask (scipy.sparse, SuperLU).
    flat_beyond_mm : float, optional
        Wavelength (mm) beyond which the surface is a plane (a flat sample):
        the best-fit plane and longer shape are removed (module docstring).
        None: the height as integrated.
    """
    p = np.asarray(p, dtype=np.float64)
    q = np.asarray(q, dtype=np.float64)
    if p.ndim != 2 or p.shape != q.shape or p.size == 0:
        raise PhotometricError(
            f"p, q: expected two (H, W) arrays of one shape, got {p.shape}, {q.shape}"
        )
    if not (np.all(np.isfinite(p)) and np.all(np.isfinite(q))):
        raise PhotometricError(
            "p, q: gradients must be finite; clip them with gradients_from_normals"
        )
    pitch = check_positive(pitch_mm, "pitch_mm")
    if flat_beyond_mm is not None:
        check_positive(flat_beyond_mm, "flat_beyond_mm")
    use = _check_mask(mask, p.shape, "mask")
    full = bool(use.all())
    if method == "auto":
        method = "dct" if full else "lsq"
    if method not in INTEGRATORS:
        raise PhotometricError(f"method: {method!r} is not one of auto, {', '.join(INTEGRATORS)}")
    gx = np.where(use, p, 0.0) * pitch  # mm per column step
    gy = np.where(use, -q, 0.0) * pitch  # mm per row step (rows run along -y)
    clipped = np.zeros(p.shape, bool)
    if not use.any():
        return HeightMap(np.zeros(p.shape, np.float32), use, clipped, method)
    if method == "dct":
        height, labels = _poisson_dct(gx, gy), use.astype(np.int64) - 1
    elif method == "fc":
        height, labels = _frankot_chellappa(gx, gy), use.astype(np.int64) - 1
    else:
        height, labels = _masked_lsq(gx, gy, use)
    if flat_beyond_mm is not None:
        height = _flattened(height, use, flat_beyond_mm / pitch)
    return HeightMap(_top_at_zero(height, labels).astype(np.float32), use, clipped, method)


def integrate_normals(
    normals,
    *,
    pitch_mm: float,
    mask=None,
    method: str = "auto",
    max_slope_deg: float = 80.0,
    flat_beyond_mm: float | None = None,
) -> HeightMap:
    """Height map from normals: :func:`gradients_from_normals` then :func:`integrate_gradients`."""
    grads = gradients_from_normals(normals, valid=mask, max_slope_deg=max_slope_deg)
    height = integrate_gradients(
        grads.p, grads.q, pitch_mm=pitch_mm, mask=mask, method=method,
        flat_beyond_mm=flat_beyond_mm,
    )  # fmt: skip
    return HeightMap(height.height_mm, height.valid, grads.clipped, height.method)


def _check_mask(mask, shape, name: str) -> np.ndarray:
    if mask is None:
        return np.ones(shape, bool)
    arr = np.asarray(mask)
    if arr.dtype != np.bool_ or arr.shape != tuple(shape):
        raise PhotometricError(
            f"{name}: expected a bool array of shape {tuple(shape)}, got {arr.dtype} {arr.shape}"
        )
    return arr


def _poisson_dct(gx: np.ndarray, gy: np.ndarray) -> np.ndarray:
    """Least-squares h for forward differences ≈ averaged gradients (Neumann boundaries)."""
    h, w = gx.shape
    rhs = np.zeros((h, w))
    dx = 0.5 * (gx[:, 1:] + gx[:, :-1])
    dy = 0.5 * (gy[1:, :] + gy[:-1, :])
    rhs[:, 1:] += dx
    rhs[:, :-1] -= dx
    rhs[1:, :] += dy
    rhs[:-1, :] -= dy
    # The DCT-II basis diagonalises the Neumann second-difference operator DᵀD.
    lam_x = 2.0 - 2.0 * np.cos(np.pi * np.arange(w) / w)
    lam_y = 2.0 - 2.0 * np.cos(np.pi * np.arange(h) / h)
    denom = lam_y[:, None] + lam_x[None, :]
    denom[0, 0] = 1.0
    spectrum = scipy.fft.dctn(rhs, type=2, norm="ortho") / denom
    spectrum[0, 0] = 0.0
    return scipy.fft.idctn(spectrum, type=2, norm="ortho")


def _frankot_chellappa(gx: np.ndarray, gy: np.ndarray) -> np.ndarray:
    """Projection of the gradient field onto integrable Fourier basis functions."""
    h, w = gx.shape
    wx = 2.0 * np.pi * scipy.fft.fftfreq(w)[None, :]
    wy = 2.0 * np.pi * scipy.fft.fftfreq(h)[:, None]
    denom = wx**2 + wy**2
    denom[0, 0] = 1.0
    spectrum = (-1j * wx * scipy.fft.fft2(gx) - 1j * wy * scipy.fft.fft2(gy)) / denom
    spectrum[0, 0] = 0.0
    return np.real(scipy.fft.ifft2(spectrum))


def _masked_lsq(gx: np.ndarray, gy: np.ndarray, use: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Sparse least squares over the mask; one pixel per connected region pinned."""
    shape = use.shape
    index = np.full(shape, -1, np.int64)
    index[use] = np.arange(int(use.sum()))
    n = int(use.sum())
    rows_a, rows_b, targets = [], [], []
    pair_h = use[:, :-1] & use[:, 1:]
    rows_a.append(index[:, :-1][pair_h])
    rows_b.append(index[:, 1:][pair_h])
    targets.append(0.5 * (gx[:, :-1] + gx[:, 1:])[pair_h])
    pair_v = use[:-1, :] & use[1:, :]
    rows_a.append(index[:-1, :][pair_v])
    rows_b.append(index[1:, :][pair_v])
    targets.append(0.5 * (gy[:-1, :] + gy[1:, :])[pair_v])
    a = np.concatenate(rows_a)
    b = np.concatenate(rows_b)
    target = np.concatenate(targets)
    m = len(target)
    diff = scipy.sparse.csr_matrix(
        (
            np.concatenate([np.full(m, -1.0), np.ones(m)]),
            (np.tile(np.arange(m), 2), np.concatenate([a, b])),
        ),
        shape=(m, n),
    )
    adjacency = scipy.sparse.csr_matrix((np.ones(m), (a, b)), shape=(n, n))
    _, region = scipy.sparse.csgraph.connected_components(adjacency, directed=False)
    first = np.unique(region, return_index=True)[1]
    pin = np.zeros(n)
    pin[first] = 1.0
    normal = (diff.T @ diff + scipy.sparse.diags(pin)).tocsc()
    solution = scipy.sparse.linalg.spsolve(normal, diff.T @ target)
    height = np.zeros(shape)
    height[use] = np.atleast_1d(solution)
    labels = np.full(shape, -1, np.int64)
    labels[use] = region
    return height, labels


def _flattened(height: np.ndarray, use: np.ndarray, cutoff_px: float) -> np.ndarray:
    """``height`` less its best-fit plane over ``use`` and its wavelengths longer than
    ``cutoff_px`` pixels (order-4 high-pass on the DCT's frequencies); 0 outside ``use``."""
    rows, cols = np.nonzero(use)
    basis = np.column_stack([cols, rows, np.ones(len(rows))]).astype(np.float64)
    plane, *_ = np.linalg.lstsq(basis, height[use], rcond=None)
    grid_rows, grid_cols = np.indices(height.shape)
    residual = np.where(use, height - (plane[0] * grid_cols + plane[1] * grid_rows + plane[2]), 0)
    h, w = height.shape
    # DCT-II term k spans k half-periods of the (h or w)-pixel side: frequency k / 2N per pixel
    freq = np.hypot(np.arange(h)[:, None] / (2.0 * h), np.arange(w)[None, :] / (2.0 * w))
    freq[0, 0] = np.inf  # the mean: the plane's, removed above
    keep = 1.0 / (1.0 + (1.0 / (cutoff_px * freq)) ** 8)
    kept = scipy.fft.idctn(scipy.fft.dctn(residual, type=2, norm="ortho") * keep, type=2,
                           norm="ortho")  # fmt: skip
    return np.where(use, kept, 0.0)


def _top_at_zero(height: np.ndarray, labels: np.ndarray) -> np.ndarray:
    """Shift each labelled region so its highest point is 0; unlabelled pixels → 0."""
    inside = labels >= 0
    if not inside.any():
        return np.zeros_like(height)
    n_regions = int(labels.max()) + 1
    tops = np.full(n_regions, -np.inf)
    np.maximum.at(tops, labels[inside], height[inside])
    out = np.zeros_like(height)
    out[inside] = height[inside] - tops[labels[inside]]
    return out
