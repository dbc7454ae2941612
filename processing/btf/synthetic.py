"""An analytic BTF with a known answer, for tests and ``rig bench btf``.

A height field below the reference plane (ribs and bumps, depth ≤ 0) with a
Lambertian albedo texture and a Blinn–Phong highlight, seen from view slots
and lit from light directions given in the sample frame. The normtexture of
view v shows, at texel (x, y), the surface point the view ray through
(x, y, 0) hits — approximately (x, y) + h·(v_x, v_y)/v_z, i.e. parallax — so
view slots differ the way measured ones do. Cast shadows and interreflection
are left out. Values are relative radiance, mostly in [0, 1].
"""

from __future__ import annotations

import numpy as np

from processing.btf._errors import BtfError
from rig.geometry import direction_vector, texel_centers_mm
from rig.material import check_directions

__all__ = ["SyntheticBTF"]


class SyntheticBTF:
    """A lazily rendered (n_views, n_lights, N, N, 3) float32 BTF.

    Index it like an array: ``btf[j]`` renders view slot j, ``btf[:, :, r0:r1]``
    renders a strip of texel rows of every view. Nothing is cached, so it
    stands in for a BTF too large for memory.

    Parameters
    ----------
    size : int
        N, texels per side.
    view_dirs_deg, light_dirs_deg : (n, 2)
        Sample-frame (θ, φ), degrees.
    sample_mm : float
        Side of the textured square.
    shininess, specular : float
        Blinn–Phong exponent and weight.
    """

    def __init__(
        self,
        size: int,
        view_dirs_deg,
        light_dirs_deg,
        *,
        sample_mm: float = 20.0,
        shininess: float = 40.0,
        specular: float = 0.25,
    ) -> None:
        if size < 2:
            raise BtfError(f"size = {size}: need ≥ 2 texels")
        self.views = check_directions("view_dirs_deg", view_dirs_deg, error=BtfError)
        self.lights = check_directions("light_dirs_deg", light_dirs_deg, error=BtfError)
        self.size = int(size)
        self.sample_mm = float(sample_mm)
        self.shininess = float(shininess)
        self.specular = float(specular)
        self.shape = (len(self.views), len(self.lights), self.size, self.size, 3)
        self.dtype = np.dtype(np.float32)
        self._light_vectors = direction_vector(self.lights[:, 0], self.lights[:, 1])

    def _surface(self, x: np.ndarray, y: np.ndarray):
        """Height (mm, ≤ 0), its gradient, and the RGB albedo at (x, y) mm."""
        k1, k2 = 2 * np.pi / 3.0, 2 * np.pi / 4.5
        h = -0.3 * (1 + np.sin(k1 * x)) - 0.15 * (1 + np.cos(k2 * y) * np.cos(k2 * x))
        hx = -0.3 * k1 * np.cos(k1 * x) + 0.15 * k2 * np.cos(k2 * y) * np.sin(k2 * x)
        hy = 0.15 * k2 * np.sin(k2 * y) * np.cos(k2 * x)
        weave = 0.5 + 0.5 * np.sin(2 * np.pi * (x + y) / 7.0)
        albedo = np.stack([0.35 + 0.4 * weave, 0.3 + 0.2 * weave, 0.5 - 0.2 * weave], axis=-1)
        return h, hx, hy, albedo

    def _render(self, view: int, rows: slice) -> np.ndarray:
        grid = texel_centers_mm(self.sample_mm, self.size)[rows]
        x, y = grid[..., 0], grid[..., 1]
        theta, phi = self.views[view]
        v = direction_vector(theta, phi)
        shift = np.array([v[0], v[1]]) / max(v[2], 0.2)
        h, *_ = self._surface(x, y)
        for _ in range(2):  # fixed point: where the ray through (x, y, 0) meets z = h
            h, hx, hy, albedo = self._surface(x + h * shift[0], y + h * shift[1])
        normal = np.stack([-hx, -hy, np.ones_like(hx)], axis=-1)
        normal /= np.linalg.norm(normal, axis=-1, keepdims=True)
        lights = self._light_vectors
        n_dot_l = np.clip(np.einsum("lk,ryk->lry", lights, normal), 0.0, None)
        half = lights + v
        half /= np.linalg.norm(half, axis=1, keepdims=True)
        n_dot_h = np.clip(np.einsum("lk,ryk->lry", half, normal), 0.0, None)
        highlight = self.specular * n_dot_h**self.shininess * (n_dot_l > 0)
        radiance = albedo[None] * n_dot_l[..., None] + highlight[..., None]
        return radiance.astype(np.float32)

    def __getitem__(self, key) -> np.ndarray:
        if isinstance(key, (int, np.integer)):
            if not 0 <= key < self.shape[0]:
                raise IndexError(f"view {key} outside 0…{self.shape[0] - 1}")
            return self._render(int(key), slice(None))
        if (
            isinstance(key, tuple)
            and len(key) == 3
            and key[0] == slice(None)
            and key[1] == slice(None)
            and isinstance(key[2], slice)
        ):
            return np.stack([self._render(j, key[2]) for j in range(self.shape[0])])
        raise TypeError("SyntheticBTF supports btf[j] and btf[:, :, r0:r1]")

    def __array__(self, dtype=None, copy=None) -> np.ndarray:
        full = np.stack([self._render(j, slice(None)) for j in range(self.shape[0])])
        return full if dtype is None else full.astype(dtype)
