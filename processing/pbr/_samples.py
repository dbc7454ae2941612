"""A compressed BTF's measured samples for a strip of texel rows, as the fit takes them."""

from __future__ import annotations

import numpy as np

from rig.material import CompressedBTF, GlobalSVD

__all__ = ["btf_samples"]


def btf_samples(model: CompressedBTF | GlobalSVD, rows: slice, *, slot_valid=None):
    """Every measured (view slot, light) pair of the texels in ``rows``.

    Parameters
    ----------
    model : the material's BTF
    rows : texel rows (a slice of 0…N)
    slot_valid : (n_views,) bool, False for a slot stored empty; default all True

    Returns
    -------
    samples : (T, M, C) float32, T = rows × N texels, M = n_views × n_lights pairs
        (view-major: pair j·n_lights + i is view slot j under light i)
    light, view : (M, 3) float64 unit vectors of the pairs
    pair_valid : (M,) bool, False for the pairs of an empty slot
    """
    n_views, n_lights = len(model.view_dirs_deg), len(model.light_dirs_deg)
    if isinstance(model, CompressedBTF):
        mean = model.mean[:, rows].astype(np.float32)  # (V, R, N, C)
        basis = model.basis[:, :, rows].astype(np.float32)  # (V, c, R, N, C)
        stack = np.einsum("vlk,vkrnc->vlrnc", model.weights.astype(np.float32), basis)
        stack += mean[:, None]
    else:
        maps = model.eigenmaps[:, :, rows].astype(np.float32)  # (c, L, R, N, C)
        stack = np.einsum("vk,klrnc->vlrnc", model.weights.astype(np.float32), maps)
    channels = stack.shape[-1]
    samples = stack.reshape(n_views * n_lights, -1, channels).transpose(1, 0, 2)
    light = np.tile(model.light_vectors, (n_views, 1))
    view = np.repeat(model.view_vectors, n_lights, axis=0)
    valid = np.ones(n_views, bool) if slot_valid is None else np.asarray(slot_valid, bool)
    return np.ascontiguousarray(samples), light, view, np.repeat(valid, n_lights)
