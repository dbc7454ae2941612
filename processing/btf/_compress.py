"""Compressing a whole BTF, view slot by view slot or as one global SVD.

``btf`` is any array-like of shape (n_views, n_lights, N, N, C) that can be
indexed — a NumPy array, a memory map, a zarr array of the session archive, or
a lazy source. :func:`compress_btf` reads one view slot at a time
(``btf[j]``); :func:`compress_global_svd` reads strips of texel rows across all
views (``btf[:, :, r0:r1]``), so neither holds the whole BTF in memory.

References
----------
.. [1] Sattler, Sarlette, Klein. EGSR 2003, §4.1 (per-view PCA).
.. [2] Wang et al. "Capturing and rendering geometry details for BTF-mapped
   surfaces." The Visual Computer 21, 2005, §5 (SVD of the 6-D BTF).
"""

from __future__ import annotations

import numpy as np

from processing.btf._errors import BtfError
from processing.btf._pca import RANK_TOL, compress_view
from rig.material import CompressedBTF, GlobalSVD, check_directions

__all__ = ["compress_btf", "compress_global_svd"]

_STRIP_VALUES = 1 << 22  # float64 values per strip of the global SVD (32 MiB)


def _shape(btf) -> tuple[int, int, int, int]:
    shape = tuple(getattr(btf, "shape", ()))
    if len(shape) != 5 or shape[4] not in (1, 3) or 0 in shape:
        raise BtfError(
            f"btf: expected an indexable (n_views, n_lights, N, N, C) array, C = 1 or 3, "
            f"got shape {shape}"
        )
    if shape[2] != shape[3]:
        raise BtfError(
            f"btf: normtextures of {shape[2]} × {shape[3]} texels; a material's BTF lies on "
            "the square N × N texel grid of the sample (rig.geometry.texel_centers_mm): crop "
            "or resample each normtexture to N × N first (compress_view takes one view slot "
            "of any H × W)"
        )
    return shape[0], shape[1], shape[2], shape[4]


def compress_btf(
    btf, *, view_dirs_deg, light_dirs_deg, components: int, storage=np.float16
) -> CompressedBTF:
    """Per-view-slot PCA of a BTF, one slot in memory at a time.

    Parameters
    ----------
    btf : (n_views, n_lights, N, N, C) array-like
        Normtextures; ``btf[j]`` must give view slot j as an array.
    view_dirs_deg : (n_views, 2)
        Sample-frame (θ, φ) of the views, degrees.
    light_dirs_deg : (n_lights, 2)
        Sample-frame (θ, φ) of the lights, degrees.
    components : int
        c per slot.
    storage : float16 or float32
        dtype of the means and bases.

    Returns
    -------
    CompressedBTF
    """
    n_views, n_lights, n, c = _shape(btf)
    views = check_directions("view_dirs_deg", view_dirs_deg, n_views, error=BtfError)
    lights = check_directions("light_dirs_deg", light_dirs_deg, n_lights, error=BtfError)
    dtype = np.dtype(storage)
    mean = np.empty((n_views, n, n, c), dtype)
    basis = np.empty((n_views, components, n, n, c), dtype)
    weights = np.empty((n_views, n_lights, components), np.float32)
    singular = np.empty((n_views, n_lights), np.float32)
    rank = np.empty(n_views, np.int32)
    for j in range(n_views):
        slot = compress_view(np.asarray(btf[j]), components=components, storage=dtype)
        mean[j], basis[j], weights[j] = slot.mean, slot.basis, slot.weights
        singular[j], rank[j] = slot.singular_values, slot.rank
    return CompressedBTF(views, lights, mean, basis, weights, singular, rank)


def compress_global_svd(
    btf, *, view_dirs_deg, light_dirs_deg, components: int, storage=np.float16
) -> GlobalSVD:
    """The SVD of seed 001 §5: rows (x, y, θl, φl), columns views; no centring.

    The views × views Gram matrix AᵀA is accumulated over strips of texel
    rows, its eigenvectors are the view weights W, and a second pass over the
    strips gives the eigenmaps E_k = A W_k / σ_k.

    Parameters
    ----------
    btf, view_dirs_deg, light_dirs_deg, storage :
        As in :func:`compress_btf`; ``btf[:, :, r0:r1]`` must give a strip.
    components : int
        c, eigenmaps kept (seed 001 keeps 4).

    Returns
    -------
    GlobalSVD
    """
    n_views, n_lights, n, c = _shape(btf)
    views = check_directions("view_dirs_deg", view_dirs_deg, n_views, error=BtfError)
    lights = check_directions("light_dirs_deg", light_dirs_deg, n_lights, error=BtfError)
    if components < 1:
        raise BtfError(f"components = {components}: must be ≥ 1")
    dtype = np.dtype(storage)
    if dtype not in (np.float16, np.float32):
        raise BtfError(f"storage = {dtype}: valid are float16 (the material) and float32")
    rows = max(1, _STRIP_VALUES // (n_views * n_lights * n * c))
    strips = [slice(r, min(r + rows, n)) for r in range(0, n, rows)]

    def strip_matrix(s: slice) -> np.ndarray:
        block = np.asarray(btf[:, :, s], dtype=np.float64)
        if not np.all(np.isfinite(block)):
            raise BtfError("btf contains NaN or inf; mask or repair those texels first")
        return block.reshape(n_views, -1).T  # rows (light, y, x, channel), columns views

    gram = np.zeros((n_views, n_views))
    for s in strips:
        a = strip_matrix(s)
        gram += a.T @ a
    eigval, eigvec = np.linalg.eigh(gram)
    eigval, eigvec = np.clip(eigval[::-1], 0.0, None), eigvec[:, ::-1]
    singular = np.sqrt(eigval)
    significant = eigval > RANK_TOL * eigval[0] if eigval[0] > 0 else np.zeros(n_views, bool)
    rank = int(min(components, np.count_nonzero(significant)))
    eigenmaps = np.zeros((components, n_lights, n, n, c))
    for s in strips:
        a = strip_matrix(s)
        part = (a @ (eigvec[:, :rank] / singular[:rank])).T  # (rank, rows of A in strip)
        eigenmaps[:rank, :, s] = part.reshape(rank, n_lights, s.stop - s.start, n, c)
    weights = np.zeros((n_views, components))
    weights[:, :rank] = eigvec[:, :rank] * singular[:rank]
    for k in range(rank):
        flat = eigenmaps[k].reshape(-1)
        scale = flat[int(np.argmax(np.abs(flat)))]
        eigenmaps[k] /= scale
        weights[:, k] *= scale
    return GlobalSVD(
        views, lights, eigenmaps.astype(dtype), weights.astype(np.float32),
        singular.astype(np.float32), rank,
    )  # fmt: skip
