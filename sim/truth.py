"""Ground truth by ray casting the scene mesh — independent of the rasteriser.

Everything here finds surfaces with :class:`sim.raycast.RayCaster` (trimesh,
Embree) and never touches GL, so comparing it with rendered frames checks the
rasteriser, the camera conventions and the shading at once.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass

import numpy as np

from rig.geometry import direction_vector, texel_centers_mm
from sim.illumination import direct_radiance, visible_from
from sim.model import SceneModel
from sim.sensor import full_scale
from sim.shading import LightSource, SurfaceHits, reflected_radiance, triangle_hits
from sim.world import WorldSnapshot

__all__ = [
    "FOOTPRINT_RAYS",
    "TexelTruth",
    "Truth",
    "btf_truth",
    "camera_hits",
    "camera_truth",
    "image_truth",
    "mdf_truth",
    "texel_truth",
]

_ABOVE_MM = 1e-4  # rays start this far above the reference plane

#: Rays per side of a texel's footprint in the texel truths (k × k rays per
#: texel). A texel is an area: the camera integrates over pixels and registration
#: resamples them onto the grid, so its truth is the mean over the footprint.
#: Regular sub-texel centres converge by about 7 dB per doubling on the bumps
#: and the weave at 64² texels; 8 gives 37.7 / 34.6 dB between 4 and 8 rays per
#: side. A comparison that needs more asks for it (``studies.footprint``).
FOOTPRINT_RAYS = 8


@dataclass(frozen=True)
class Truth:
    """What each pixel of a camera sees (pinhole, no lens distortion), sample frame.

    mask : (H, W) bool, a surface is hit
    part : (H, W) int8, −1 nothing, 0 plate, 1 recess walls/floor, 2 sample
    points : (H, W, 3) float32 mm; normals : (H, W, 3) float32 unit
    albedo : (H, W, 3) float32; height : (H, W) float32 z of the hit, mm
    lit : lamp id → (H, W) bool, the lamp sees the point (cast shadows)
    Unhit pixels hold zeros (see ``mask``).
    """

    mask: np.ndarray
    part: np.ndarray
    points: np.ndarray
    normals: np.ndarray
    albedo: np.ndarray
    height: np.ndarray
    lit: dict[str, np.ndarray]


@dataclass(frozen=True)
class TexelTruth:
    """Normals, albedo and height on the texel grid, seen from straight above.

    normals (n, n, 3) float32, albedo (n, n, 3) float32, height (n, n) float32
    (z ≤ 0, mm), part (n, n) int8; row 0 at +y, column 0 at −x.
    """

    normals: np.ndarray
    albedo: np.ndarray
    height: np.ndarray
    part: np.ndarray


def camera_hits(model: SceneModel, camera_id: str, turntable_deg: float) -> SurfaceHits:
    """Ray-cast hits of every pixel centre of a camera (pinhole)."""
    camera = model.camera(camera_id)
    origin, dirs = model.camera_rays(camera, turntable_deg)
    faces = model.caster.first_faces(origin, dirs)
    pixels = np.flatnonzero(faces >= 0)
    shape = (camera.height, camera.width)
    return model.hits(shape, pixels, origin, dirs[pixels], faces[pixels])


def _image(hits: SurfaceHits, values: np.ndarray, fill=0.0) -> np.ndarray:
    out = np.full((*hits.shape, *values.shape[1:]), fill, dtype=np.float32)
    out.reshape(-1, *values.shape[1:])[hits.pixels] = values
    return out


def camera_truth(
    model: SceneModel, camera_id: str, turntable_deg: float, *, arc_deg: float, lamps
) -> Truth:
    """Per-pixel truth for a camera and turntable angle (see :class:`Truth`)."""
    hits = camera_hits(model, camera_id, turntable_deg)
    snap = WorldSnapshot(0.0, turntable_deg, arc_deg, frozenset(lamps), False, 0.0, 0)
    lit = {
        lamp_id: _image(hits, visible_from(model, hits, light.position, offset_mm=1e-3)) > 0
        for lamp_id, light in model.lights(snap).items()
    }
    part = np.full(hits.shape, -1, dtype=np.int8)
    part.reshape(-1)[hits.pixels] = hits.parts
    return Truth(
        mask=part >= 0,
        part=part,
        points=_image(hits, hits.points),
        normals=_image(hits, hits.normals),
        albedo=_image(hits, hits.albedo),
        height=_image(hits, hits.points[:, 2]),
        lit=lit,
    )


def image_truth(
    model: SceneModel, camera_id: str, snapshot: WorldSnapshot, exposure_s: float
) -> np.ndarray:
    """Noise-free camera image (float32 DN) shaded from ray-cast hits.

    Applies the scene's listed shading effects (shadows, specular, laser) and
    none of the lens or sensor effects (vignetting, distortion, noise,
    saturation, quantisation); pinhole geometry.
    """
    scene = model.scene
    spec = scene.rig.camera(camera_id)
    hits = camera_hits(model, camera_id, snapshot.turntable_deg)
    offset = scene.spec.params("shadows").offset_mm if scene.has("shadows") else 1e-3

    def shadows(_lamp_id, light, lit):
        return visible_from(model, hits, light.position, offset_mm=offset, where=lit)

    values = direct_radiance(
        model, hits, snapshot, counters=Counter(),
        shadow_mask=shadows if scene.has("shadows") else None,
        laser=scene.spec.params("laser") if scene.has("laser") else None,
        specular=scene.has("specular"), offset_mm=offset,
    )  # fmt: skip
    scale = exposure_s / scene.spec.radiometry.full_scale_exposure * full_scale(spec.bit_depth)
    image = _image(hits, values * scale)
    return image.mean(axis=2) if spec.channels == 1 else image


def texel_hits(model: SceneModel, view_dir, n: int) -> tuple[SurfaceHits, np.ndarray]:
    """Hits along −v from the texel centres just above the reference plane."""
    v = direction_vector(*view_dir)
    if v[2] <= 0:
        raise ValueError(f"view_dir {tuple(view_dir)}: θ must be < 90° (above the sample)")
    xy = texel_centers_mm(model.sample_mm, n).reshape(-1, 2)
    origins = np.column_stack([xy, np.full(len(xy), _ABOVE_MM)])
    dirs = np.broadcast_to(-v, origins.shape).copy()
    faces = model.caster.first_faces(origins, dirs)
    pixels = np.flatnonzero(faces >= 0)
    hits = model.hits((n, n), pixels, origins[pixels], dirs[pixels], faces[pixels])
    t, _, _ = triangle_hits(origins[hits.pixels], dirs[hits.pixels], model.mesh.vertices[
        model.mesh.faces[hits.faces]])  # fmt: skip
    return hits, t - _ABOVE_MM / v[2]


def mdf_truth(model: SceneModel, view_dir, n: int) -> np.ndarray:
    """The MDF D_v on the n×n texel grid: (n, n) float32 mm, −1 where nothing is hit.

    D_v(x, y) is the distance along the view ray from (x, y, 0) down to the
    first surface (seed ``001_…``, §4); ``view_dir`` = (θ, φ) degrees, sample
    frame, pointing away from the surface. One ray per texel centre: a distance
    along a ray has no footprint mean (averaging a depth edge invents a
    surface that is nowhere), and the scanner's MDF is resampled at the same
    texel centres.
    """
    hits, dist = texel_hits(model, view_dir, n)
    out = _image(hits, np.clip(dist, 0, None), fill=-1.0)
    return out


def _footprint_mean(image: np.ndarray, rays: int) -> np.ndarray:
    """(n·k, n·k, ...) → (n, n, ...) float32: the mean over each texel's k × k
    sub-texels (``texel_centers_mm(s, n·k)`` splits every texel of the n-grid
    into k × k, in the same row/column order)."""
    n = image.shape[0] // rays
    blocks = image.reshape(n, rays, n, rays, *image.shape[2:])
    return blocks.mean(axis=(1, 3), dtype=np.float64).astype(np.float32)


def _rays(rays: int) -> int:
    if int(rays) != rays or rays < 1:
        raise ValueError(f"rays={rays}: rays per texel side must be an integer ≥ 1")
    return int(rays)


def texel_truth(model: SceneModel, n: int, *, rays: int = FOOTPRINT_RAYS) -> TexelTruth:
    """Normals, albedo, height and part on the texel grid, seen from above.

    Each texel is the mean over its footprint, ``rays`` × ``rays`` vertical
    rays (1: the texel centre alone): albedo and height the mean, the normal
    the normalised mean (what a photometric fit of the texel's mean radiance
    finds on a Lambertian surface), the part the one most rays hit.
    """
    k = _rays(rays)
    hits, _ = texel_hits(model, (0.0, 0.0), n * k)
    part = np.full((n * k, n * k), -1, dtype=np.int8)
    part.reshape(-1)[hits.pixels] = hits.parts
    counts = np.stack([_footprint_mean((part == p).astype(np.float32), k) for p in (-1, 0, 1, 2)])
    normals = _footprint_mean(_image(hits, hits.normals), k)
    length = np.linalg.norm(normals, axis=-1, keepdims=True)
    return TexelTruth(
        normals=np.divide(normals, length, out=np.zeros_like(normals), where=length > 0),
        albedo=_footprint_mean(_image(hits, hits.albedo), k),
        height=_footprint_mean(_image(hits, hits.points[:, 2]), k),
        part=(np.argmax(counts, axis=0) - 1).astype(np.int8),
    )


def btf_truth(
    model: SceneModel, view_dir, light_dir, n: int, *, rays: int = FOOTPRINT_RAYS
) -> np.ndarray:
    """Noise-free BTF slice on the texel grid: (n, n, 3) float32, 1/sr.

    The radiance towards ``view_dir`` per unit irradiance from a distant
    light in ``light_dir`` (both (θ, φ) degrees, sample frame):
    ``(ρ/π + f_s) · cosθ_i`` — with cast shadows when the scene lists
    ``shadows`` and the specular lobe when it lists ``specular``. Texels see
    along the view rays through (x, y, 0), as a rectified normtexture does;
    each texel is the mean over its footprint, ``rays`` × ``rays`` rays
    through its sub-texel centres (1: the texel centre alone).
    """
    scene = model.scene
    k = _rays(rays)
    hits, _ = texel_hits(model, view_dir, n * k)
    light = direction_vector(*light_dir)
    dirs = np.broadcast_to(light, hits.points.shape)
    e = np.ones(len(hits.points))
    if scene.has("shadows"):
        far = LightSource(light * 1e7, "point", 1.0)
        offset = scene.spec.params("shadows").offset_mm
        e = e * visible_from(model, hits, far.position, offset_mm=offset)
    lobes = model.specular if scene.has("specular") else None
    return _footprint_mean(_image(hits, reflected_radiance(hits, dirs, e, lobes)), k)
