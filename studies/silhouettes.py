"""Mesostructure silhouettes against the truth (seed 001 §4.1, Fig. 10).

The simulator's sample geometry — the Gaussian bumps (a height field) and the
plain weave (yarns over a floor: not a height field) — is wrapped onto a
cylinder and a torus by the shell map the renderer assumes: a point (x, y, z)
of the sample at tile (i, j) goes to S(u, v) + s·z·n(u, v), with (u, v) the
surface's UVs of (x, y) in that tile and s = tile_mm / sample_mm. Ray casting
that geometry (trimesh) from the renderer's camera, through the same pixel
centres, gives the true coverage; the renderer draws the smooth mesh with the
material's BTF, once without the MDF and once with it (depth peeling), and
each coverage mask is scored against the truth:

- ``iou``: |rendered ∩ true| / |rendered ∪ true|;
- ``band_px``: the pixels where the two disagree per pixel of the true
  outline, the mean width of the error band along it in pixels.

The material's MDF is the sample's exact one: rays from the texel centres of
the reference plane down each view direction of H1 (81 slots to 85°) into the
sample tiled 5 × 5 (so grazing rays meet the neighbouring repeats, as on the
surface), D the distance to the first hit. Its BTF is the synthetic one of
``processing.btf.synthetic`` (it colours the pictures; coverage does not
depend on it).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache
from pathlib import Path

import numpy as np
import trimesh

from processing.btf import compress_btf
from processing.btf.synthetic import SyntheticBTF
from render import Camera, DirectionalLight, Renderer
from render.meshes import Mesh, cylinder, mesh_from_arrays, torus
from render.output import write_png
from rig.geometry import Sampling
from rig.material import Material, Mdf
from sim.samples import generator
from sim.samples.heightfields import BumpsParams
from sim.samples.weave import WeaveParams
from studies.mdf_truth import ray_cast_mdf

__all__ = [
    "SHAPES",
    "SilhouetteCase",
    "run",
    "run_silhouettes",
    "sample_mdf",
    "scores",
    "write_figure",
]

SAMPLE_MM = 16.0  # one repeat: 2 × 2 bumps, 4 × 4 yarns
TILE_MM = 16.0  # true scale; the shapes hold whole repeats around
SHAPES = ("cylinder", "torus")
_PARAMS = {
    "bumps": BumpsParams(amplitude_mm=2.5, spacing_mm=8.0, sigma_mm=2.0, grid=129),
    "weave": WeaveParams(),
}
_DEPTH_MM = 3.0  # the recess the generators check against
_LIGHT = (0.4, -0.6, 0.7)


@cache
def _sample(name: str):
    """The sample's triangles (sample frame, mm) and its floor depth (None for height fields)."""
    geometry = generator(name).build(_PARAMS[name], sample_mm=SAMPLE_MM, depth_mm=_DEPTH_MM)
    floor = None if geometry.height is not None else float(geometry.vertices[:, 2].min())
    return geometry, floor


def _tiled_sample(name: str, copies: int) -> trimesh.Trimesh:
    """The sample repeated (2·copies + 1)² times, with its floor under a non-height field."""
    geometry, floor = _sample(name)
    parts, faces, offset = [], [], 0
    shifts = np.arange(-copies, copies + 1) * SAMPLE_MM
    for dx in shifts:
        for dy in shifts:
            parts.append(geometry.vertices + np.array([dx, dy, 0.0]))
            faces.append(geometry.faces + offset)
            offset += len(geometry.vertices)
    if floor is not None:
        e = SAMPLE_MM * (copies + 0.5)
        parts.append(np.array([[-e, -e, floor], [e, -e, floor], [e, e, floor], [-e, e, floor]]))
        faces.append(np.array([[0, 1, 2], [0, 2, 3]]) + offset)
    return trimesh.Trimesh(np.concatenate(parts), np.concatenate(faces), process=False)


def sample_mdf(name: str, *, size: int = 64, views_deg=None) -> Mdf:
    """The exact MDF of sample ``name`` on a size² texel grid at ``views_deg`` (H1's by default)."""
    views = Sampling.named("H1").directions if views_deg is None else np.asarray(views_deg)
    return ray_cast_mdf(_tiled_sample(name, copies=2), views, sample_mm=SAMPLE_MM, n=size,
                        source=f"ray cast {name}")  # fmt: skip


def _shell(shape: str):
    """The renderer's mesh of ``shape`` and its surface point and normal at UVs (mm)."""
    if shape == "torus":
        major, minor = 8 * TILE_MM / np.pi, 3 * TILE_MM / np.pi  # 16 × 6 whole repeats

        def surface(u, v):
            phi, psi = u / major, v / minor
            n = np.stack([np.cos(psi) * np.cos(phi), np.cos(psi) * np.sin(phi), np.sin(psi)], -1)
            return n * minor + np.stack([major * np.cos(phi), major * np.sin(phi), 0 * phi], -1), n

        return torus(major_mm=major, minor_mm=minor, segments=96), surface, (16, 6)
    radius, height = 3 * TILE_MM / np.pi, 8 * TILE_MM  # 6 repeats around, 8 along

    def surface(u, v):
        n = np.stack([np.cos(u / radius), np.sin(u / radius), 0 * u], -1)
        return n * radius + np.stack([0 * u, 0 * u, v - height / 2], -1), n

    return _capped(cylinder(radius_mm=radius, height_mm=height, segments=96)), surface, (6, 8)


def _capped(tube: Mesh) -> Mesh:
    """The tube closed by a flat disc at each end (a fan on its rim vertices), as the
    MDF silhouettes need a closed object; the caps' UVs are their x, y in mm."""
    positions, uvs, normals = [tube.positions], [tube.uvs], [tube.normals]
    faces, count = [tube.faces.astype(np.int64)], len(tube.positions)
    for end, sign in ((tube.positions[:, 2].max(), 1.0), (tube.positions[:, 2].min(), -1.0)):
        rim = np.flatnonzero(np.isclose(tube.positions[:, 2], end))
        angle = np.round(np.arctan2(tube.positions[rim, 1], tube.positions[rim, 0]), 9)
        rim = rim[np.unique(np.mod(angle, 2 * np.pi).round(9), return_index=True)[1]]  # seam once
        ring = np.vstack([[0.0, 0.0, end], tube.positions[rim]])
        positions.append(ring)
        uvs.append(ring[:, :2] + 100.0)
        normals.append(np.tile([0.0, 0.0, sign], (len(ring), 1)))
        k = np.arange(1, len(ring))
        fan = np.stack([np.zeros_like(k), k, np.roll(k, -1)], axis=1)
        faces.append((fan if sign > 0 else fan[:, ::-1]) + count)
        count += len(ring)
    return mesh_from_arrays(np.vstack(positions), np.vstack(uvs), np.vstack(faces),
                            name="capped cylinder", normals=np.vstack(normals))  # fmt: skip


def displaced(name: str, shape: str) -> trimesh.Trimesh:
    """The sample wrapped onto ``shape`` by the shell map (the true geometry)."""
    _, surface, (n_u, n_v) = _shell(shape)
    s = TILE_MM / SAMPLE_MM
    geometry, floor = _sample(name)
    if geometry.height is not None:  # a fine grid of the displaced height field
        steps = round(SAMPLE_MM / 0.25)
        u, v = np.meshgrid(np.linspace(0, n_u * TILE_MM, n_u * steps + 1),
                           np.linspace(0, n_v * TILE_MM, n_v * steps + 1))  # fmt: skip
        x = (np.mod(u / TILE_MM, 1.0) - 0.5) * SAMPLE_MM
        y = (np.mod(v / TILE_MM, 1.0) - 0.5) * SAMPLE_MM
        point, normal = surface(u, v)
        vertices = point + s * geometry.height(x, y)[..., None] * normal
        i = np.arange(u.size).reshape(u.shape)
        a, b, c, d = i[:-1, :-1].ravel(), i[:-1, 1:].ravel(), i[1:, 1:].ravel(), i[1:, :-1].ravel()
        faces = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
        return trimesh.Trimesh(vertices.reshape(-1, 3), faces, process=False)
    parts, faces, offset = [], [], 0
    x, y, z = geometry.vertices.T
    for i in range(n_u):
        for j in range(n_v):
            u, v = (x / SAMPLE_MM + 0.5 + i) * TILE_MM, (y / SAMPLE_MM + 0.5 + j) * TILE_MM
            point, normal = surface(u, v)
            parts.append(point + s * z[:, None] * normal)
            faces.append(geometry.faces + offset)
            offset += len(x)
    core, _, _ = _shell(shape)  # the floor: the surface moved in by the floor's depth
    parts.append(core.positions + s * floor * core.normals)
    faces.append(core.faces.astype(np.int64) + offset)
    return trimesh.Trimesh(np.concatenate(parts), np.concatenate(faces), process=False)


def camera_for(shape: str, size: int) -> Camera:
    """The camera both the renderer and the ray caster see ``shape`` from."""
    if shape == "torus":
        return Camera.perspective((0, -300, 80), (0, 0, -4), fov_deg=22, size=(size, size))
    # The tube across the view, its ends outside the frame.
    return Camera.perspective((-60, -160, 25), (0, 0, 0), up=(0.6, 0, 1), fov_deg=26,
                              size=(size, size))  # fmt: skip


def truth_image(mesh: trimesh.Trimesh, camera: Camera) -> tuple[np.ndarray, np.ndarray]:
    """(H, W) bool coverage and (H, W, 3) Lambert shading of ``mesh`` through the
    camera's pixel centres, row 0 at the top (as ``Renderer.coverage``)."""
    width, height = camera.size
    start, dirs = (a.reshape(-1, 3) for a in camera.pixel_rays())
    faces, rays = mesh.ray.intersects_id(start, dirs, multiple_hits=False)[:2]
    covered = np.zeros(len(dirs), bool)
    covered[rays] = True
    normals = mesh.face_normals[faces]
    facing = np.sign(-np.einsum("ij,ij->i", normals, dirs[rays]))[:, None]
    light = np.asarray(_LIGHT) / np.linalg.norm(_LIGHT)
    shade = np.zeros(len(dirs))
    shade[rays] = 0.08 + 0.8 * np.clip((facing * normals) @ light, 0, None)
    image = np.repeat(shade[:, None], 3, axis=1).reshape(height, width, 3)
    return covered.reshape(height, width), image.astype(np.float32)


def scores(mask: np.ndarray, truth: np.ndarray) -> tuple[float, float]:
    """IoU of ``mask`` with ``truth``, and the pixels where they disagree per pixel of
    length of the true outline: the error band's mean width. The outline's length is
    its count of pixel edges between inside and outside times π/4, which the edge
    count overestimates by 4/π on average over orientations (exact for a disc)."""
    union = np.logical_or(mask, truth).sum()
    iou = float(np.logical_and(mask, truth).sum() / union) if union else 1.0
    padded = np.pad(truth, 1)
    edges = (padded[1:] != padded[:-1]).sum() + (padded[:, 1:] != padded[:, :-1]).sum()
    return iou, float((mask != truth).sum() / max(edges * np.pi / 4, 1.0))


@dataclass(frozen=True)
class SilhouetteCase:
    """One sample on one shape: the rows' numbers and the three pictures (the MDF's
    with two peeling passes, or the most run if fewer)."""

    sample: str
    shape: str
    rows: list[dict]
    btf_only: np.ndarray
    with_mdf: np.ndarray
    truth: np.ndarray


def _material(name: str, mdf_size: int) -> Material:
    views, lights = Sampling.named("H2").directions[::3], Sampling.named("H1").directions
    synthetic = SyntheticBTF(16, views, lights, sample_mm=SAMPLE_MM)
    btf = compress_btf(synthetic, view_dirs_deg=views, light_dirs_deg=lights, components=4)
    return Material(Path(f"silhouettes-{name}"), SAMPLE_MM, 16, btf, np.ones(len(views), bool),
                    mdf=sample_mdf(name, size=mdf_size))  # fmt: skip


def run_silhouettes(*, samples=("bumps", "weave"), shapes=SHAPES, size: int = 256,
                    peels=(2,), mdf_size: int = 64) -> list[SilhouetteCase]:  # fmt: skip
    """Render and ray cast every sample on every shape; see the module."""
    light = [DirectionalLight(_LIGHT)]
    cases = []
    for name in samples:
        material = _material(name, mdf_size)
        for shape in shapes:
            mesh = _shell(shape)[0]
            camera = camera_for(shape, size)
            truth, truth_picture = truth_image(displaced(name, shape), camera)
            rows, pictures = [], {}
            for mdf, peel in [(False, 0), *((True, p) for p in peels)]:
                with Renderer(material, mesh, tile_mm=TILE_MM, mdf=mdf, peel=max(peel, 1),
                              shadows=False) as renderer:  # fmt: skip
                    if not mdf or peel == min(max(peels), 2):  # the default 2 passes shown
                        pictures[mdf] = renderer.render(camera, light)
                    iou, band = scores(renderer.coverage(camera), truth)
                rows.append({"sample": name, "shape": shape, "mdf": mdf, "peel": peel,
                             "iou": round(iou, 4), "band_px": round(band, 2)})  # fmt: skip
            cases.append(SilhouetteCase(name, shape, rows, pictures[False], pictures[True],
                                        truth_picture))  # fmt: skip
    return cases


def write_figure(path, cases: list[SilhouetteCase]) -> Path:
    """A PNG: a row per case, BTF only | BTF + MDF | truth, each row cropped to what
    its pictures show (the rendered ones scaled so their brightest 1 % is at 90 % white)."""
    rows = []
    for case in cases:
        scale = 0.9 / max(float(np.percentile(case.btf_only, 99)), 1e-6)
        row = np.hstack([case.btf_only * scale, case.with_mdf * scale, case.truth])
        shown = np.flatnonzero(row.sum(axis=(1, 2)) > 0)
        rows.append(row[max(shown[0] - 4, 0) : shown[-1] + 5])
    return write_png(path, np.vstack(rows))


def run(quick: bool = False) -> list[dict]:
    """``rig bench silhouettes``: rows ``sample``, ``shape``, ``mdf``, ``peel`` (0 without
    the MDF), ``iou``, ``band_px`` (see the module). ``quick``: the bumps on the torus at
    128², one and two passes; else both samples on both shapes at 256², 1–3 passes."""
    if quick:
        cases = run_silhouettes(samples=("bumps",), shapes=("torus",), size=128, peels=(1, 2))
    else:
        cases = run_silhouettes(peels=(1, 2, 3))
    return [row for case in cases for row in case.rows]
