"""Exact shading of ray hits: hit reconstruction, lamps, reflectance.

The rasteriser and the ray caster only decide *which* triangle a ray hits;
:func:`triangle_hits` then intersects the ray with that triangle in float64,
so both paths shade the same exact point and differ only where they pick a
different triangle (silhouettes). Radiance of a Lambertian surface lit by a
point lamp of radiant intensity I at distance r (m):

    L = ρ/π · I · cosθ_i / r²          (W · sr⁻¹ · m⁻²)

with ρ the albedo and θ_i the angle between the normal and the lamp.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, fields

import numpy as np
from numba import njit

from rig.config import Lamp
from sim.materials import Specular, eval_specular, specular_view_terms

__all__ = ["LightSource", "SurfaceHits", "reflected_radiance", "surface_radiance", "triangle_hits"]


def triangle_hits(
    origins: np.ndarray, dirs: np.ndarray, triangles: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Möller–Trumbore intersection of rays with their triangles (float64).

    Parameters
    ----------
    origins : (n, 3) or (3,)
    dirs : (n, 3) ray directions
    triangles : (n, 3, 3) vertices of each ray's triangle

    Returns
    -------
    t, u, v : (n,) ray parameter and barycentrics of vertices 1 and 2
        (the hit is ``(1-u-v)·a + u·b + v·c``); rays parallel to their
        triangle get t = inf.
    """
    a, b, c = triangles[:, 0], triangles[:, 1], triangles[:, 2]
    e1, e2 = b - a, c - a
    p = np.cross(dirs, e2)
    det = np.einsum("ij,ij->i", e1, p)
    ok = np.abs(det) > 1e-14
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    s = origins - a
    u = np.einsum("ij,ij->i", s, p) * inv
    q = np.cross(s, e1)
    v = np.einsum("ij,ij->i", dirs, q) * inv
    t = np.where(ok, np.einsum("ij,ij->i", e2, q) * inv, np.inf)
    return t, u, v


@dataclass(frozen=True)
class SurfaceHits:
    """What each hit pixel sees, sample frame.

    pixels : (n,) int64 flat indices into the (H, W) image
    points : (n, 3) float64 mm; normals : (n, 3) float64 unit, facing the viewer
    faces, materials : (n,) int64; parts : (n,) int8
    view_dirs : (n, 3) float64 unit, from the point towards the camera
    albedo : (n, 3) float64
    memo : what :meth:`reuse` keeps (not part of the hits' value)
    """

    shape: tuple[int, int]
    pixels: np.ndarray
    points: np.ndarray
    normals: np.ndarray
    faces: np.ndarray
    materials: np.ndarray
    parts: np.ndarray
    view_dirs: np.ndarray
    albedo: np.ndarray
    memo: dict = field(default_factory=dict, compare=False, repr=False)

    def reuse(self, key, compute: Callable[[], object]):
        """``compute()``, kept with these hits under ``key``: a term that depends on
        the hits (the view) only, shared by every lamp that lights them."""
        if key not in self.memo:
            self.memo[key] = compute()
        return self.memo[key]

    @classmethod
    def build(cls, mesh, shape, pixels, origins, dirs, faces, albedo_fn) -> SurfaceHits:
        """Reconstruct exact hits of rays ``dirs`` (n, 3) on their ``faces`` (n,): the
        :func:`triangle_hits` point, its barycentric vertex normal facing the viewer
        (seen from behind: inside a yarn end, under the plate) and the view direction,
        in one compiled pass: numpy's arithmetic (to the order of the last bits)."""
        n = len(faces)
        points, normals, view = np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3))
        keep = np.empty(n, dtype=np.bool_)
        _exact_hits(np.asarray(origins, np.float64).reshape(-1, 3), np.asarray(dirs, np.float64),
                    np.asarray(faces, np.int64), mesh.vertices, mesh.faces, mesh.normals,
                    points, normals, view, keep)  # fmt: skip
        if not keep.all():
            pixels, faces, points, normals, view = (
                pixels[keep], faces[keep], points[keep], normals[keep], view[keep]
            )  # fmt: skip
        materials = mesh.face_material[faces]
        return cls(
            shape=shape,
            pixels=pixels,
            points=points,
            normals=normals,
            faces=faces,
            materials=materials,
            parts=mesh.face_part[faces],
            view_dirs=view,
            albedo=albedo_fn(points, materials),
        )

    @classmethod
    def concatenate(cls, parts: list[SurfaceHits]) -> SurfaceHits:
        """The hits of one image, from ``parts`` built over consecutive runs of its pixels."""
        arrays = [f.name for f in fields(cls) if f.name not in ("shape", "memo")]
        joined = {name: np.concatenate([getattr(p, name) for p in parts]) for name in arrays}
        return cls(shape=parts[0].shape, **joined)

    @property
    def nbytes(self) -> int:
        """Bytes the hit arrays and what :meth:`reuse` kept hold."""
        arrays = [getattr(self, f.name) for f in fields(self) if f.name not in ("shape", "memo")]
        return _nbytes(arrays) + _nbytes(list(self.memo.values()))


@njit(cache=True, nogil=True)
def _exact_hits(origins, dirs, faces, vertices, triangles, vertex_normals, points, normals,
                view, keep):  # fmt: skip
    """:meth:`SurfaceHits.build`'s arithmetic ray by ray, as numpy's (:func:`triangle_hits`,
    the interpolation, the norms) does it; ``keep`` False for a ray parallel to its face
    or hitting it behind the origin (its other outputs are then undefined)."""
    many = origins.shape[0] > 1
    for i in range(faces.shape[0]):
        o = origins[i] if many else origins[0]
        d = dirs[i]
        ia, ib, ic = triangles[faces[i], 0], triangles[faces[i], 1], triangles[faces[i], 2]
        a, b, c = vertices[ia], vertices[ib], vertices[ic]
        e1x, e1y, e1z = b[0] - a[0], b[1] - a[1], b[2] - a[2]
        e2x, e2y, e2z = c[0] - a[0], c[1] - a[1], c[2] - a[2]
        px, py, pz = d[1] * e2z - d[2] * e2y, d[2] * e2x - d[0] * e2z, d[0] * e2y - d[1] * e2x
        det = e1x * px + e1y * py + e1z * pz
        if not abs(det) > 1e-14:
            keep[i] = False
            continue
        inv = 1.0 / det
        sx, sy, sz = o[0] - a[0], o[1] - a[1], o[2] - a[2]
        u = (sx * px + sy * py + sz * pz) * inv
        qx, qy, qz = sy * e1z - sz * e1y, sz * e1x - sx * e1z, sx * e1y - sy * e1x
        v = (d[0] * qx + d[1] * qy + d[2] * qz) * inv
        t = (e2x * qx + e2y * qy + e2z * qz) * inv
        keep[i] = math.isfinite(t) and t > 0
        w = 1 - u - v
        na, nb, nc = vertex_normals[ia], vertex_normals[ib], vertex_normals[ic]
        length = 0.0
        for k in range(3):
            points[i, k] = o[k] + t * d[k]
            normals[i, k] = w * na[k] + u * nb[k] + v * nc[k]
            length = length + normals[i, k] * normals[i, k] if k else normals[i, k] * normals[i, k]
        d_length = math.sqrt((d[0] * d[0] + d[1] * d[1]) + d[2] * d[2])
        length = math.sqrt(length)
        facing = 0.0
        for k in range(3):
            normals[i, k] = normals[i, k] / length
            view[i, k] = -d[k] / d_length
            facing = facing + normals[i, k] * view[i, k] if k else normals[i, k] * view[i, k]
        if facing < 0:
            for k in range(3):
                normals[i, k] = -normals[i, k]


def _nbytes(value) -> int:
    """Bytes of the arrays in ``value`` (an array, or tuples and lists of them)."""
    if isinstance(value, tuple | list):
        return sum(_nbytes(item) for item in value)
    return getattr(value, "nbytes", 0)


@dataclass(frozen=True)
class LightSource:
    """A lamp in the sample frame.

    position : (3,) mm; kind ``point``, ``spot`` or ``directional``;
    intensity_w_sr : radiant intensity (a directional lamp gives the
    irradiance a point lamp at its position gives at the turntable centre);
    cutoff_deg : spot half-angle around the axis towards the turntable centre.
    """

    position: np.ndarray
    kind: str
    intensity_w_sr: float
    cutoff_deg: float = 90.0

    @classmethod
    def from_lamp(cls, lamp: Lamp, position: np.ndarray, intensity_w_sr: float) -> LightSource:
        return cls(position, lamp.kind, lamp.intensity * intensity_w_sr, lamp.spot_cutoff_deg)

    def incident(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Unit directions towards the lamp (n, 3) and normal irradiance (n,), W/m²."""
        if self.kind == "directional":
            r = np.linalg.norm(self.position)
            dirs = np.broadcast_to(self.position / r, points.shape)
            return dirs, np.full(len(points), self.intensity_w_sr / (r / 1000.0) ** 2)
        to_lamp = self.position - points
        r = np.linalg.norm(to_lamp, axis=1)
        dirs = to_lamp / r[:, None]
        e = self.intensity_w_sr / (r / 1000.0) ** 2
        if self.kind == "spot":
            axis = -self.position / np.linalg.norm(self.position)
            cos_off = np.einsum("ij,j->i", -dirs, axis)
            e = np.where(cos_off >= np.cos(np.deg2rad(self.cutoff_deg)), e, 0.0)
        return dirs, e

    def surface_irradiance(
        self, points: np.ndarray, normals: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Unit directions towards the lamp (n, 3) and the irradiance on the surface
        (n,), ``E · max(cosθ_i, 0)`` W/m², for unit ``normals`` (n, 3): what
        :meth:`incident` and the cosine give, a point or spot lamp's in one compiled pass."""
        if self.kind == "directional":
            dirs, e = self.incident(points)
            return dirs, e * np.clip(np.einsum("ij,ij->i", normals, dirs), 0, None)
        dirs = np.empty_like(points)
        e = np.empty(len(points))
        spot = self.kind == "spot"
        axis = -self.position / np.linalg.norm(self.position)
        cos_cut = np.cos(np.deg2rad(self.cutoff_deg)) if spot else -2.0
        _point_irradiance(np.ascontiguousarray(self.position, np.float64),
                          float(self.intensity_w_sr), np.ascontiguousarray(axis, np.float64),
                          float(cos_cut), points, normals, dirs, e)  # fmt: skip
        return dirs, e


@njit(cache=True, nogil=True)
def _point_irradiance(position, intensity, axis, cos_cut, points, normals, dirs, e):
    """:meth:`LightSource.surface_irradiance` of a point lamp (``cos_cut`` −2) or a spot."""
    for i in range(points.shape[0]):
        x = position[0] - points[i, 0]
        y = position[1] - points[i, 1]
        z = position[2] - points[i, 2]
        r = math.sqrt(x * x + y * y + z * z)
        x, y, z = x / r, y / r, z / r
        dirs[i, 0], dirs[i, 1], dirs[i, 2] = x, y, z
        r_m = r / 1000.0
        value = intensity / (r_m * r_m)
        if -(x * axis[0] + y * axis[1] + z * axis[2]) < cos_cut:
            value = 0.0
        cos_i = normals[i, 0] * x + normals[i, 1] * y + normals[i, 2] * z
        e[i] = value * cos_i if cos_i > 0.0 else 0.0


def reflected_radiance(
    hits: SurfaceHits,
    light_dirs: np.ndarray,
    irradiance: np.ndarray,
    specular: dict[int, Specular] | None,
) -> np.ndarray:
    """Radiance (n, 3) W/(sr·m²) towards the viewer: (ρ/π + f_s) · E · cosθ_i.

    ``specular`` maps material index → lobe; None leaves the surface
    Lambertian (the ``specular`` effect is not listed).
    """
    cos_i = np.clip(np.einsum("ij,ij->i", hits.normals, light_dirs), 0, None)
    return surface_radiance(hits, light_dirs, irradiance * cos_i, specular)


def surface_radiance(
    hits: SurfaceHits,
    light_dirs: np.ndarray,
    e: np.ndarray,
    specular: dict[int, Specular] | None,
) -> np.ndarray:
    """:func:`reflected_radiance` for the irradiance on the surface, ``e`` (n,) =
    E · max(cosθ_i, 0) W/m² (:meth:`LightSource.surface_irradiance`)."""
    radiance = hits.albedo / np.pi * e[:, None]
    for material, lobe in (specular or {}).items():
        sel, normals, views, terms = hits.reuse(
            ("specular", material), lambda m=material, lobe=lobe: _specular_view(hits, m, lobe)
        )
        if len(sel):
            f = eval_specular(lobe, normals, light_dirs[sel], views, terms)
            radiance[sel] += (f * e[sel])[:, None]
    return radiance


def _specular_view(hits: SurfaceHits, material: int, lobe: Specular) -> tuple:
    """The hits of one material, their normals and views, and the lobe's view terms."""
    sel = np.flatnonzero(hits.materials == material)
    normals, views = hits.normals[sel], hits.view_dirs[sel]
    return sel, normals, views, specular_view_terms(lobe, normals, views)
