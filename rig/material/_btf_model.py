"""Compressed BTFs: per-view PCA slots, or one global SVD, with their direction tables."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rig.errors import RigError
from rig.geometry import direction_vector
from rig.material._errors import MaterialError

__all__ = ["CompressedBTF", "GlobalSVD", "check_directions"]


def check_directions(
    name: str,
    dirs_deg,
    count: int | None = None,
    *,
    error: type[RigError] = MaterialError,
) -> np.ndarray:
    """(n, 2) float64 (θ, φ) degrees, θ in [0, 90]; ``error`` naming ``name`` otherwise.

    ``error`` is the caller's domain error: a stored direction table that is
    wrong is a :class:`MaterialError`, a wrong argument to a compression a
    ``processing.btf.BtfError``.
    """
    try:
        d = np.asarray(dirs_deg, dtype=np.float64)
    except (TypeError, ValueError) as err:
        raise error(f"{name}: expected (n, 2) [theta_deg, phi_deg] numbers ({err})") from None
    if d.ndim != 2 or d.shape[1] != 2 or len(d) == 0 or not np.all(np.isfinite(d)):
        raise error(f"{name}: expected finite (n, 2) [theta_deg, phi_deg], got shape {d.shape}")
    if count is not None and len(d) != count:
        raise error(f"{name}: {len(d)} directions for {count} measured images")
    if np.any((d[:, 0] < 0) | (d[:, 0] > 90)):
        raise error(f"{name}: theta must lie in [0, 90] (the upper hemisphere)")
    return d


class _Directions:
    """Unit vectors of a BTF's direction tables (``view_dirs_deg``, ``light_dirs_deg``)."""

    view_dirs_deg: np.ndarray
    light_dirs_deg: np.ndarray

    @property
    def view_vectors(self) -> np.ndarray:
        return direction_vector(self.view_dirs_deg[:, 0], self.view_dirs_deg[:, 1])

    @property
    def light_vectors(self) -> np.ndarray:
        return direction_vector(self.light_dirs_deg[:, 0], self.light_dirs_deg[:, 1])


@dataclass(frozen=True)
class CompressedBTF(_Directions):
    """A BTF as per-view-slot PCA (seed 000 eq. (1)).

    normtexture(view j, light i) ≈ mean[j] + Σ_k weights[j, i, k] · basis[j, k].

    Attributes
    ----------
    view_dirs_deg : (n_views, 2) float64
        Sample-frame (θ, φ) of the view slots, degrees.
    light_dirs_deg : (n_lights, 2) float64
        Sample-frame (θ, φ) of the measured lights, degrees (shared by all slots).
    mean : (n_views, N, N, C) float16 or float32
    basis : (n_views, c, N, N, C) float16 or float32
        Each eigennormtexture scaled to max |B| = 1.
    weights : (n_views, n_lights, c) float32
    singular_values : (n_views, n_lights) float32
    rank : (n_views,) int32
        Components used per slot (≤ c).
    """

    view_dirs_deg: np.ndarray
    light_dirs_deg: np.ndarray
    mean: np.ndarray
    basis: np.ndarray
    weights: np.ndarray
    singular_values: np.ndarray
    rank: np.ndarray

    @property
    def components(self) -> int:
        return self.basis.shape[1]

    @property
    def size(self) -> int:
        return self.mean.shape[1]

    @property
    def nbytes(self) -> int:
        """Bytes of the arrays a renderer needs (means, bases, weights)."""
        return self.mean.nbytes + self.basis.nbytes + self.weights.nbytes

    def reconstruct_view(self, view: int) -> np.ndarray:
        """All lights of one view slot: (n_lights, N, N, C) float32."""
        basis = self.basis[view].astype(np.float32)
        stack = np.tensordot(self.weights[view], basis, axes=1)
        return stack + self.mean[view].astype(np.float32)

    def blend(self, view_idx, view_w, light_idx, light_w) -> np.ndarray:
        """Σ_v ω_v Σ_l τ_l normtexture(v, l) in one pass per view slot (seed 000 eq. (3), (5)).

        ``view_idx``/``view_w`` (k_v,) and ``light_idx``/``light_w`` (k_l,); the
        light weights combine the PCA weights first (γ = Σ τ p), so each slot
        costs one weighted sum of its c bases. Returns (N, N, C) float32.
        """
        out = np.zeros(self.mean.shape[1:], np.float64)
        lw = np.asarray(light_w, dtype=np.float64)
        for v, w in zip(np.asarray(view_idx), np.asarray(view_w, dtype=np.float64), strict=True):
            if w == 0.0:
                continue
            gamma = lw @ self.weights[v, np.asarray(light_idx)].astype(np.float64)  # (c,)
            slot = self.mean[v].astype(np.float64) * lw.sum()
            slot += np.tensordot(gamma, self.basis[v].astype(np.float64), axes=1)
            out += w * slot
        return out.astype(np.float32)


@dataclass(frozen=True)
class GlobalSVD(_Directions):
    """A BTF as one SVD over all views (seed 001 §5).

    The matrix A has a row per (light, y, x, channel) and a column per view:
    A ≈ E diag(1) Wᵀ, i.e. normtexture(view j, light i) ≈ Σ_k weights[j, k] ·
    eigenmaps[k, i].

    Attributes
    ----------
    view_dirs_deg, light_dirs_deg :
        As in :class:`CompressedBTF`.
    eigenmaps : (c, n_lights, N, N, C) float16 or float32
        The 4-D eigenmaps E_k(x, y, θl, φl), each scaled to max |E_k| = 1.
    weights : (n_views, c) float32
        W_k(θv, φv).
    singular_values : (n_views,) float32
    rank : int
    """

    view_dirs_deg: np.ndarray
    light_dirs_deg: np.ndarray
    eigenmaps: np.ndarray
    weights: np.ndarray
    singular_values: np.ndarray
    rank: int

    @property
    def components(self) -> int:
        return self.eigenmaps.shape[0]

    @property
    def size(self) -> int:
        return self.eigenmaps.shape[2]

    @property
    def nbytes(self) -> int:
        return self.eigenmaps.nbytes + self.weights.nbytes

    def reconstruct_view(self, view: int) -> np.ndarray:
        """All lights of one view: (n_lights, N, N, C) float32."""
        return np.tensordot(self.weights[view], self.eigenmaps.astype(np.float32), axes=1)

    def blend(self, view_idx, view_w, light_idx, light_w) -> np.ndarray:
        """Σ_v ω_v Σ_l τ_l normtexture(v, l); returns (N, N, C) float32."""
        omega = np.asarray(view_w, dtype=np.float64) @ self.weights[np.asarray(view_idx)]
        out = np.zeros(self.eigenmaps.shape[2:], np.float64)
        for li, tau in zip(
            np.asarray(light_idx), np.asarray(light_w, dtype=np.float64), strict=True
        ):
            if tau == 0.0:
                continue
            out += tau * np.tensordot(omega, self.eigenmaps[:, li].astype(np.float64), axes=1)
        return out.astype(np.float32)
