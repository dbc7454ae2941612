"""Shadow boundaries on a BTF + MDF plane against the ray-cast truth (seed 001 §4.2, Fig. 8).

A ball floats over a plane whose sample is the simulator's Gaussian bumps
(``sim.samples``, height field h ≤ 0 under the reference plane z = 0), tiled
at ``tile_mm`` per repeat, so the relief is the sample's scaled by s =
``tile_mm`` / ``sample_mm`` (the texture scale of seed 001). A directional
light casts the ball's shadow onto it, an orthographic camera looks on.

- **Truth**: the true relief as a triangle mesh, each pixel's ray cast
  (trimesh) to its first hit, that point lit unless the ray towards the light
  meets the ball. Only the ball's shadow counts: the relief's shadows on
  itself are the BTF's business (its normtextures hold them), as in the seed.
- **Renderer**: the same scene as the flat plane + the ball, the material a
  constant BTF (T ≡ 1, so a pixel's value is the light's lit fraction there)
  with the relief's MDF, ray cast from the same height field at every view
  slot. Without the MDF the shadow map is tested at the reference plane; with
  it at the mesostructure point p − s·D(x, y, v)·v.

The score is the fraction of the plane's pixels (the truth sees relief there,
not the ball) whose lit/shadow state agrees, over the whole plane and within
a band around the true shadow boundary.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh
from scipy import ndimage

from render import Camera, DirectionalLight, Renderer
from render.meshes import Mesh, merged, plane, sphere
from render.output import write_png
from rig.geometry import Sampling, direction_vector
from rig.material import CompressedBTF, Material, Mdf
from sim.samples import generator
from sim.samples.heightfields import BumpsParams
from studies.mdf_truth import ray_cast_mdf

__all__ = [
    "QUICK_SCENE",
    "ShadowScene",
    "TruthShadow",
    "relief_mdf",
    "relief_mesh",
    "run",
    "run_check",
    "scene_mesh",
    "truth_shadow",
    "write_figure",
]


@dataclass(frozen=True)
class ShadowScene:
    """The check's scene: sizes in mm, directions (θ, φ) in degrees, world frame."""

    sample_mm: float = 20.0
    texels: int = 64
    amplitude_mm: float = 1.5
    spacing_mm: float = 5.0
    sigma_mm: float = 1.2
    tile_mm: float = 40.0
    plane_mm: float = 80.0
    ball_mm: float = 12.0
    ball_height_mm: float = 18.0
    light_deg: tuple[float, float] = (45.0, 0.0)
    camera_deg: tuple[float, float] = (35.0, 180.0)
    size: int = 256
    relief_step_mm: float = 0.1
    #: half-width of the band around the true shadow boundary that is scored apart, pixels
    band_px: int = 10

    @property
    def scale(self) -> float:
        """s: scene mm per sample mm."""
        return self.tile_mm / self.sample_mm

    def height(self):
        """h(x, y) of the sample, sample mm, z ≤ 0 (``sim.samples`` bumps)."""
        params = BumpsParams(
            amplitude_mm=self.amplitude_mm, spacing_mm=self.spacing_mm, sigma_mm=self.sigma_mm
        )
        build = generator("bumps").build
        return build(params, sample_mm=self.sample_mm, depth_mm=2 * self.amplitude_mm).height

    def camera(self) -> Camera:
        eye = direction_vector(*self.camera_deg) * 3 * self.plane_mm
        return Camera.orthographic(eye, (0, 0, 0), height=self.plane_mm * 1.05,
                                   size=(self.size, self.size))  # fmt: skip

    def light(self) -> DirectionalLight:
        return DirectionalLight(tuple(direction_vector(*self.light_deg)))


def relief_mesh(height, *, sample_mm: float, scale: float, extent_mm: float, step_mm: float):
    """The relief a plane tiled with the sample shows: z = s·h(sample point), as a mesh.

    The plane's texture coordinate (uv / tile_mm, as the renderer maps it, with
    uv = x + extent/2) picks the sample point: the texel grid of
    ``rig.geometry.texel_centers_mm`` centred on the sample, its −x, −y corner at
    texture coordinate 0. ``extent_mm``: the side of the square covered, centred
    on the origin. Returns a ``trimesh.Trimesh`` (scene mm).
    """
    tile = scale * sample_mm
    edge = np.arange(0.0, extent_mm + step_mm / 2, step_mm)
    u, v = np.meshgrid(edge, edge)
    sx = (np.mod(u / tile, 1.0) - 0.5) * sample_mm
    sy = (np.mod(v / tile, 1.0) - 0.5) * sample_mm
    z = scale * height(sx.ravel(), sy.ravel())
    vertices = np.column_stack([u.ravel() - extent_mm / 2, v.ravel() - extent_mm / 2, z])
    n = len(edge)
    i = np.arange(n * n).reshape(n, n)
    a, b, c, d = i[:-1, :-1].ravel(), i[:-1, 1:].ravel(), i[1:, 1:].ravel(), i[1:, :-1].ravel()
    faces = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    return trimesh.Trimesh(vertices, faces, process=False, validate=False)


def relief_mdf(height, view_dirs_deg, *, sample_mm: float, n: int, step_mm: float) -> Mdf:
    """The exact MDF of a periodic height field (``studies.mdf_truth``), its relief
    meshed at ``step_mm`` and tiled 3 × 3 so slanted rays find the neighbours' relief."""
    tiles = relief_mesh(height, sample_mm=sample_mm, scale=1.0, extent_mm=3 * sample_mm,
                        step_mm=step_mm)  # fmt: skip
    return ray_cast_mdf(tiles, view_dirs_deg, sample_mm=sample_mm, n=n,
                        source="ray cast from the sample's height field")  # fmt: skip


def _ball(scene: ShadowScene) -> Mesh:
    ball = sphere(radius_mm=scene.ball_mm, segments=48)
    lift = np.float32([0.0, 0.0, scene.ball_height_mm])
    return dataclasses.replace(ball, positions=ball.positions + lift)


def scene_mesh(scene: ShadowScene) -> Mesh:
    """The flat plane (z = 0, the reference surface) and the ball above it, one mesh."""
    return merged([plane(size_mm=scene.plane_mm, segments=8), _ball(scene)], name="plane and ball")


@dataclass(frozen=True)
class TruthShadow:
    """What each pixel of the check's camera truly sees: ``relief`` (H, W) bool, the
    relief is the first thing hit (not the ball, not nothing); ``lit`` (H, W) bool, that
    point sees the light past the ball."""

    relief: np.ndarray
    lit: np.ndarray


def truth_shadow(scene: ShadowScene) -> TruthShadow:
    """Cast the camera's pixel rays at the true relief and the ball, then towards the light."""
    relief = relief_mesh(scene.height(), sample_mm=scene.sample_mm, scale=scene.scale,
                         extent_mm=scene.plane_mm, step_mm=scene.relief_step_mm)  # fmt: skip
    ball_mesh = _ball(scene)
    ball = trimesh.Trimesh(ball_mesh.positions, ball_mesh.faces, process=False)
    both = trimesh.util.concatenate([relief, ball])
    origins, dirs = scene.camera().pixel_rays()
    origins, dirs = origins.reshape(-1, 3), dirs.reshape(-1, 3)
    faces = both.ray.intersects_first(origins, dirs)
    on_relief = (faces >= 0) & (faces < len(relief.faces))
    hit_rays = np.flatnonzero(on_relief)
    points, rays, _ = relief.ray.intersects_location(
        origins[hit_rays], dirs[hit_rays], multiple_hits=False
    )
    lit = np.zeros(len(origins), bool)
    to_light = np.broadcast_to(direction_vector(*scene.light_deg), points.shape)
    lit[hit_rays[rays]] = ~ball.ray.intersects_any(points, to_light)
    shape = (scene.size, scene.size)
    return TruthShadow(relief=on_relief.reshape(shape), lit=lit.reshape(shape))


def _shadow_material(scene: ShadowScene, view_dirs_deg) -> Material:
    """A grey BTF that reads 1 on the plane under the scene's light, at every view: a
    Lambertian texture, cos θ_i / cos θ_light under measured light i (the light blend carries
    the cosine, so the plane's blend is cos θ_light / cos θ_light), with the relief's MDF."""
    n, views = scene.texels, np.asarray(view_dirs_deg, np.float64)
    lights = Sampling.named("H1").directions
    n_views, n_lights = len(views), len(lights)
    lambert = np.cos(np.radians(lights[:, 0])) / np.cos(np.radians(scene.light_deg[0]))
    btf = CompressedBTF(
        views, lights, np.zeros((n_views, n, n, 1), np.float16),
        np.ones((n_views, 1, n, n, 1), np.float16),
        np.broadcast_to(lambert[None, :, None], (n_views, n_lights, 1)).astype(np.float32),
        np.ones((n_views, n_lights), np.float32), np.ones(n_views, np.int32),
    )  # fmt: skip
    mdf = relief_mdf(scene.height(), views, sample_mm=scene.sample_mm, n=n,
                     step_mm=scene.relief_step_mm / 2)  # fmt: skip
    return Material(Path("mdf shadow check"), scene.sample_mm, n, btf, np.ones(n_views, bool),
                    mdf=mdf)  # fmt: skip


def _rendered_lit(
    scene: ShadowScene, material: Material, *, mdf: bool, shadows: bool = True
) -> np.ndarray:
    """(H, W) float32: the light's lit fraction per pixel of the plane, as the renderer
    shades it (the probe BTF under a unit light, no ambient term; on the ball, its shading
    relative to the plane's); 0 where nothing is seen."""
    with Renderer(material, scene_mesh(scene), tile_mm=scene.tile_mm, mdf=mdf,
                  shadows=shadows, ambient=0.0) as renderer:  # fmt: skip
        return renderer.render(scene.camera(), [scene.light()])[..., 0]


def _boundary_band(truth: TruthShadow, scored: np.ndarray, band_px: int) -> np.ndarray:
    """Scored pixels with both a lit and a shadowed relief pixel within ``band_px``."""
    lit, shadow = truth.relief & truth.lit, truth.relief & ~truth.lit
    near_lit = ndimage.distance_transform_edt(~lit) <= band_px
    near_shadow = ndimage.distance_transform_edt(~shadow) <= band_px
    return scored & near_lit & near_shadow


def run_check(scene: ShadowScene | None = None, *, views=None) -> dict:
    """Lit/shadow agreement with the truth, without and with the MDF.

    Scored are the pixels where the truth sees the relief and the renderer the
    plane (the flat plane's outline is not the relief's: silhouettes are
    another matter). Returns ``rows`` (``mdf`` off/on, ``agreement`` over the
    scored pixels, ``band_agreement`` within ``band_px`` of the true boundary,
    the pixel counts) and the images (``truth``, ``lit_off``, ``lit_on``, and
    ``scored``, the mask).
    ``views``: the MDF's view slots, every third direction of H2 (27) by default.
    """
    scene = ShadowScene() if scene is None else scene
    views = Sampling.named("H2").directions[::3] if views is None else views
    truth = truth_shadow(scene)
    material = _shadow_material(scene, views)
    scored = truth.relief & (_rendered_lit(scene, material, mdf=False, shadows=False) > 0.5)
    band = _boundary_band(truth, scored, scene.band_px)
    rows, images = [], {"truth": truth, "scored": scored}
    for mdf in (False, True):
        lit = _rendered_lit(scene, material, mdf=mdf)
        agree = (lit > 0.5) == truth.lit
        images[f"lit_{'on' if mdf else 'off'}"] = lit
        rows.append({
            "mdf": "on" if mdf else "off",
            "agreement": round(float(agree[scored].mean()), 4),
            "band_agreement": round(float(agree[band].mean()), 4),
            "pixels": int(scored.sum()), "band_pixels": int(band.sum()),
        })  # fmt: skip
    return {"rows": rows, **images}


#: ``--quick``: the check at a quarter of the pixels, the relief meshed at 0.2 mm.
QUICK_SCENE = ShadowScene(size=128, band_px=5, relief_step_mm=0.2)


def run(quick: bool = False) -> list[dict]:
    """``rig bench mdf-shadows``: the rows of :func:`run_check` (``mdf`` off and on),
    on :data:`QUICK_SCENE` when ``quick``, else on the 256² scene."""
    return run_check(QUICK_SCENE if quick else ShadowScene())["rows"]


def write_figure(path, check: dict) -> Path:
    """A PNG: without the MDF | with it | truth. Lit relief light grey, shadowed dark
    grey, scored pixels where a render disagrees with the truth red; the ball, the
    background and the pixels not scored black."""
    truth, scored = check["truth"], check["scored"]

    def panel(seen: np.ndarray, lit: np.ndarray, wrong: np.ndarray) -> np.ndarray:
        grey = np.where(seen, np.where(lit, 0.7, 0.08), 0.0)
        image = np.repeat(grey[..., None], 3, axis=2)
        image[wrong] = (0.9, 0.0, 0.0)
        return image

    panels = [panel(truth.relief, truth.lit, np.zeros_like(truth.lit))]
    for name in ("lit_on", "lit_off"):
        lit = check[name] > 0.5
        panels.insert(0, panel(scored, lit, scored & (lit != truth.lit)))
    gap = np.ones((truth.lit.shape[0], 4, 3))
    return write_png(path, np.hstack([panels[0], gap, panels[1], gap, panels[2]]))
