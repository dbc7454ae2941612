"""Per-view-slot PCA of a BTF (seed 000 §4.1, eq. (1)), one view at a time.

For one view slot the n_lights normtextures are the rows of X (n_lights × D,
D = N·N·3). With the mean m over the lights and Xc = X − m, the eigenvectors
U and eigenvalues λ of the small Gram matrix G = Xc Xcᵀ (n_lights × n_lights)
give the principal directions of Xc without its D × D covariance or a full
SVD: the k-th eigennormtexture is B_k = Xcᵀ U_k / √λ_k and the weight of
light i is p_ik = √λ_k U_ik, so that N_i ≈ m + Σ_k p_ik B_k. X is streamed in
column blocks in float64 (two passes), so the working memory beyond the input
is a few blocks, and the whole BTF never sits in memory: only one view does.

For texture-ready storage each B_k is scaled to max |B_k| = 1 (its scale
moves into the weights) and its sign is fixed by making its largest entry
positive.

References
----------
.. [1] Sattler, Sarlette, Klein. "Efficient and realistic visualization of
   cloth." EGSR 2003, §4.1.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from processing.btf._errors import BtfError
from processing.btf._interpolate import Method, light_weights
from rig.geometry import direction_vector
from rig.material import CompressedBTF, check_directions

__all__ = ["ViewSlot", "compress_view", "compress_view_svd"]

#: Components with λ_k ≤ RANK_TOL · λ_1 (σ below 1e-6 σ_1) count as rank deficiency.
RANK_TOL = 1e-12
_BLOCK = 1 << 16


@dataclass(frozen=True)
class ViewSlot:
    """The compressed normtextures of one view slot.

    Attributes
    ----------
    mean : (H, W, C) storage dtype
        Mean normtexture over the lights (H = W = N for a material's slot).
    basis : (c, H, W, C) storage dtype
        Eigennormtextures, each scaled to max |B_k| = 1; zero beyond ``rank``.
    weights : (n_lights, c) float32
        p_ik: normtexture i ≈ mean + Σ_k weights[i, k] · basis[k].
    singular_values : (n_lights,) float32
        √λ of all components (descending), for choosing c.
    rank : int
        Components actually used, ≤ c (less for a constant view, fewer
        lights than components, duplicated lights).
    """

    mean: np.ndarray
    basis: np.ndarray
    weights: np.ndarray
    singular_values: np.ndarray
    rank: int

    def reconstruct(self, light: int) -> np.ndarray:
        """The compressed normtexture of measured light ``light``: (H, W, C) float32."""
        n_lights = len(self.weights)
        if not 0 <= light < n_lights:
            raise BtfError(f"light = {light}: valid are 0 ≤ light < {n_lights}")
        return self._slot().blend([0], [1.0], [light], [1.0])

    def interpolate(self, light_deg, *, light_dirs_deg, method: Method = "nearest4") -> np.ndarray:
        """The normtexture for any light direction (θ, φ) degrees: (H, W, C) float32.

        ``light_dirs_deg`` (n_lights, 2): the measured lights, in the order of the
        stack this slot compresses. The lights blend as in
        :func:`processing.btf.interpolate` (exactly :meth:`reconstruct` at a
        measured direction), without a whole :class:`CompressedBTF`.
        """
        lights = check_directions(
            "light_dirs_deg", light_dirs_deg, len(self.weights), error=BtfError
        )
        vectors = direction_vector(lights[:, 0], lights[:, 1])
        index, weight = light_weights(vectors, light_deg, method=method)
        return self._slot().blend([0], [1.0], index, weight)

    def _slot(self) -> CompressedBTF:
        # This slot as a one-view model (views of the arrays, no copy): one blend for both.
        n_lights = len(self.weights)
        return CompressedBTF(
            np.zeros((1, 2)), np.zeros((n_lights, 2)), self.mean[None], self.basis[None],
            self.weights[None], self.singular_values[None], np.array([self.rank], np.int32),
        )  # fmt: skip


def _check_stack(stack) -> np.ndarray:
    x = np.asarray(stack)
    if x.ndim != 4 or x.shape[3] not in (1, 3) or x.shape[0] < 1 or 0 in x.shape:
        raise BtfError(
            f"view stack: expected (n_lights, H, W, C) with C = 1 or 3, got shape {x.shape}"
        )
    if not (np.issubdtype(x.dtype, np.floating) or np.issubdtype(x.dtype, np.integer)):
        raise BtfError(f"view stack: expected a real-valued array, got dtype {x.dtype}")
    if np.issubdtype(x.dtype, np.floating) and not np.all(np.isfinite(x)):
        raise BtfError("view stack contains NaN or inf; mask or repair those texels first")
    return x


def _check_storage(components: int, storage) -> np.dtype:
    if components < 1:
        raise BtfError(f"components = {components}: must be ≥ 1")
    dtype = np.dtype(storage)
    if dtype not in (np.float16, np.float32):
        raise BtfError(f"storage = {dtype}: valid are float16 (the material) and float32")
    return dtype


def _finish(
    mean: np.ndarray,
    basis_unit: np.ndarray,
    weights: np.ndarray,
    singular: np.ndarray,
    rank: int,
    shape: tuple[int, ...],
    storage: np.dtype,
) -> ViewSlot:
    """Scale each basis to max |B| = 1, fix signs, and store."""
    c = weights.shape[1]
    for k in range(rank):
        peak = int(np.argmax(np.abs(basis_unit[k])))
        scale = basis_unit[k, peak]
        basis_unit[k] /= scale
        weights[:, k] *= scale
    basis_unit[rank:] = 0.0
    weights[:, rank:] = 0.0
    limit = np.finfo(storage).max
    if np.abs(mean).max(initial=0.0) > limit:
        raise BtfError(
            f"the mean normtexture reaches {np.abs(mean).max():.4g}, beyond {storage} "
            f"(max {limit:.4g}); scale the BTF (e.g. to radiance in [0, 1]) first"
        )
    return ViewSlot(
        mean.reshape(shape).astype(storage),
        basis_unit.reshape(c, *shape).astype(storage),
        weights.astype(np.float32),
        singular.astype(np.float32),
        rank,
    )


def compress_view(stack, *, components: int, storage=np.float16) -> ViewSlot:
    """PCA of one view slot's normtextures through the lights × lights Gram matrix.

    Parameters
    ----------
    stack : (n_lights, H, W, C) array, C ∈ {1, 3}, float or integer
        The normtextures of one view slot, one per light direction; H ≠ W is
        fine here (a material's slots are N × N: :func:`compress_btf`). Values
        as they are: decode 8-bit sRGB to linear first (:func:`to_linear`).
    components : int
        c, eigennormtextures kept (the seed uses ≤ 16).
    storage : float16 or float32
        dtype of ``mean`` and ``basis`` (float16 is the material's).

    Returns
    -------
    ViewSlot
        With ``rank`` = min(c, numerical rank of the centred stack).

    Examples
    --------
    >>> stack = np.random.default_rng(0).random((8, 4, 4, 3), dtype=np.float32)
    >>> slot = compress_view(stack, components=7, storage=np.float32)
    >>> bool(np.allclose(slot.reconstruct(2), stack[2], atol=1e-5))
    True
    """
    x = _check_stack(stack)
    dtype = _check_storage(components, storage)
    n, shape = x.shape[0], x.shape[1:]
    flat = x.reshape(n, -1)
    d = flat.shape[1]
    blocks = [slice(i, min(i + _BLOCK, d)) for i in range(0, d, _BLOCK)]
    mean = np.empty(d)
    gram = np.zeros((n, n))
    for b in blocks:
        xb = flat[:, b].astype(np.float64)
        mean[b] = xb.mean(axis=0)
        xb -= mean[b]
        gram += xb @ xb.T
    eigval, eigvec = np.linalg.eigh(gram)
    eigval, eigvec = np.clip(eigval[::-1], 0.0, None), eigvec[:, ::-1]
    singular = np.sqrt(eigval)
    significant = eigval > RANK_TOL * eigval[0] if eigval[0] > 0 else np.zeros(n, bool)
    rank = int(min(components, np.count_nonzero(significant)))
    weights = np.zeros((n, components))
    basis = np.zeros((components, d))
    if rank:
        u = eigvec[:, :rank]
        project = u / singular[:rank]
        for b in blocks:
            xb = flat[:, b].astype(np.float64) - mean[b]
            basis[:rank, b] = project.T @ xb
        weights[:, :rank] = u * singular[:rank]
    return _finish(mean, basis, weights, singular, rank, shape, dtype)


def compress_view_svd(stack, *, components: int, storage=np.float16) -> ViewSlot:
    """The same PCA through ``numpy.linalg.svd`` of the centred stack (the baseline).

    Same parameters and result as :func:`compress_view`; it holds the whole
    float64 centred stack and its factors, and is several times slower.
    """
    x = _check_stack(stack)
    dtype = _check_storage(components, storage)
    n, shape = x.shape[0], x.shape[1:]
    flat = x.reshape(n, -1).astype(np.float64)
    mean = flat.mean(axis=0)
    u, s, vt = np.linalg.svd(flat - mean, full_matrices=False)
    singular = np.zeros(n)
    singular[: len(s)] = s
    significant = s**2 > RANK_TOL * s[0] ** 2 if s[0] > 0 else np.zeros(len(s), bool)
    rank = int(min(components, np.count_nonzero(significant)))
    weights = np.zeros((n, components))
    basis = np.zeros((components, flat.shape[1]))
    weights[:, :rank] = u[:, :rank] * s[:rank]
    basis[:rank] = vt[:rank]
    return _finish(mean, basis, weights, singular, rank, shape, dtype)
