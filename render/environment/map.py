"""HDR environment maps: latitude–longitude radiance around the scene, read or made.

An environment map is the radiance arriving from every direction, stored as an
(H, W, 3) latitude–longitude image with W = 2H in the scene frame of
``rig.geometry``: row r covers θ from r·180°/H to (r + 1)·180°/H measured from
+z (row 0 at the zenith), column c covers φ from c·360°/W to (c + 1)·360°/W,
the azimuth from +x towards +y. ``exposure`` (the seed's f, seed 000 eq. (11))
scales what the renderer makes of it; ``rotation_deg`` turns it about the
vertical axis: the environment rotated by δ sends from (θ, φ) what the stored
map sends from (θ, φ − δ).

Files: Radiance ``.hdr`` through OpenCV, OpenEXR ``.exr`` through the OpenEXR
bindings (OpenCV's wheels are built without EXR). :func:`synthetic_environment`
makes small test environments in code: a sky with a sun, a window in a dark
room, a studio with softboxes.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import cached_property
from pathlib import Path

import cv2
import numpy as np
import OpenEXR

from render._errors import RenderError
from rig.geometry import direction_angles, direction_vector
from rig.interchange import InterchangeError, check_image_size

__all__ = [
    "SYNTHETIC_ENVIRONMENTS",
    "EnvironmentMap",
    "read_environment",
    "synthetic_environment",
]

_SUFFIXES = (".hdr", ".exr")
SYNTHETIC_ENVIRONMENTS = ("sky", "window", "studio")


@dataclass(frozen=True)
class EnvironmentMap:
    """Radiance from every direction, a latitude–longitude image (see the module).

    Attributes
    ----------
    radiance : (H, W, 3) float32, W = 2H, finite, ≥ 0
        Radiance per pixel in the map's own units.
    exposure : float
        The factor f the renderer's output is multiplied by (> 0).
    rotation_deg : float
        Turn about +z, degrees, counter-clockwise seen from above.
    name : str
        Where it came from (a file or a synthetic name), for messages.
    """

    radiance: np.ndarray
    exposure: float = 1.0
    rotation_deg: float = 0.0
    name: str = "environment"

    def __post_init__(self) -> None:
        r = np.asarray(self.radiance, dtype=np.float32)
        if r.ndim != 3 or r.shape[2] != 3 or r.shape[0] < 2 or r.shape[1] != 2 * r.shape[0]:
            raise RenderError(
                f"environment {self.name!r}: expected an (H, 2H, 3) latitude–longitude RGB "
                f"image with H ≥ 2, got shape {r.shape}"
            )
        if not np.all(np.isfinite(r)) or np.any(r < 0):
            raise RenderError(
                f"environment {self.name!r}: radiance must be finite and ≥ 0 "
                f"({int(np.sum(~np.isfinite(r)))} NaN/inf, {int(np.sum(r < 0))} negative values)"
            )
        if not (np.isfinite(self.exposure) and self.exposure > 0):
            raise RenderError(f"environment exposure = {self.exposure}: must be a number > 0")
        if not np.isfinite(self.rotation_deg):
            raise RenderError(f"environment rotation_deg = {self.rotation_deg}: must be finite")
        r.setflags(write=False)
        object.__setattr__(self, "radiance", r)

    @property
    def height(self) -> int:
        return self.radiance.shape[0]

    def with_view(self, *, exposure: float | None = None, rotation_deg: float | None = None):
        """The same map with another exposure and/or rotation."""
        changes = {}
        if exposure is not None:
            changes["exposure"] = exposure
        if rotation_deg is not None:
            changes["rotation_deg"] = rotation_deg
        return replace(self, **changes)

    def pixel_directions(self) -> tuple[np.ndarray, np.ndarray]:
        """Unit vectors (H, W, 3) float64 of the pixel centres (rotation applied) and the
        solid angle (H, 1) float64 of each row's pixels, steradians (they sum to 4π)."""
        h = self.height
        edges = np.radians(np.arange(h + 1) * 180.0 / h)
        solid = (2 * np.pi / (2 * h)) * (np.cos(edges[:-1]) - np.cos(edges[1:]))
        theta = (np.arange(h) + 0.5) * 180.0 / h
        phi = (np.arange(2 * h) + 0.5) * 180.0 / h + self.rotation_deg
        vectors = direction_vector(theta[:, None], phi[None, :])
        return vectors, solid[:, None]

    def lookup(self, directions) -> np.ndarray:
        """Radiance (…, 3) float32 arriving from unit ``directions`` (…, 3): the pixel
        holding each (nearest, no filtering), rotation applied, exposure not."""
        d = np.asarray(directions, dtype=np.float64)
        theta, phi = direction_angles(d)
        h = self.height
        row = np.clip((theta * h / 180.0).astype(np.int64), 0, h - 1)
        col = np.floor(np.mod(phi - self.rotation_deg, 360.0) * h / 180.0).astype(np.int64)
        return self.radiance[row, np.clip(col, 0, 2 * h - 1)]

    def mean_lookup(self, directions, width_rad) -> np.ndarray:
        """Radiance (…, 3) float64 averaged over about ``width_rad`` (…) around unit
        ``directions`` (…, 3), rotation applied, exposure not.

        A point lookup of a map whose features are smaller than the spacing of the
        directions asked for catches them or misses them (a 3° sun between the 20°
        texels of a hemicube: six times its light or none). Here each direction reads
        the level of a pyramid of solid-angle weighted 2 × 2 means whose pixel is nearest
        ``width_rad`` wide (by its logarithm), bilinearly: a sum over directions spaced
        about one such pixel apart keeps a small bright source's light wherever it falls.
        (The next coarser level would keep it better still but blurs sharp-edged lights
        more than a texel: see ``docs/render.md``.)
        """
        d = np.asarray(directions, dtype=np.float64)
        width = np.broadcast_to(np.asarray(width_rad, dtype=np.float64), d.shape[:-1])
        theta, phi = direction_angles(d)
        ratio = np.maximum(width / (np.pi / self.height), 1.0)
        level = np.minimum(np.rint(np.log2(ratio)).astype(np.int64), len(self._means) - 1)
        out = np.empty((*d.shape[:-1], 3))
        for index in np.unique(level):
            chosen = level == index
            out[chosen] = _bilinear(
                self._means[index], theta[chosen], phi[chosen] - self.rotation_deg
            )
        return out

    @cached_property
    def _means(self) -> list[np.ndarray]:
        """Level 0 the map, each next level the solid-angle weighted mean of 2 × 2 pixels,
        while the height halves evenly (float64)."""
        levels = [self.radiance.astype(np.float64)]
        h = self.height
        edges = np.radians(np.arange(h + 1) * 180.0 / h)
        row_solid = np.cos(edges[:-1]) - np.cos(edges[1:])  # ∝ each row's pixel solid angle
        while levels[-1].shape[0] % 2 == 0 and levels[-1].shape[0] > 2:
            r = levels[-1]
            rows = r.shape[0]
            light = (r * row_solid[:, None, None]).reshape(rows // 2, 2, rows, 2, 3).sum((1, 3))
            row_solid = row_solid.reshape(-1, 2).sum(axis=1)
            levels.append(light / (2.0 * row_solid[:, None, None]))
        return levels


def _bilinear(image: np.ndarray, theta_deg: np.ndarray, phi_deg: np.ndarray) -> np.ndarray:
    """(m, 3) bilinear samples of a latitude–longitude ``image`` (h, 2h, 3): pixel centres at
    (i + ½) · 180°/h, repeating in φ, held at the first and last row in θ."""
    h = image.shape[0]
    y = theta_deg * (h / 180.0) - 0.5
    x = np.mod(phi_deg, 360.0) * (h / 180.0) - 0.5
    y0, x0 = np.floor(y), np.floor(x)
    fy, fx = (y - y0)[:, None], (x - x0)[:, None]
    rows = np.clip(np.stack([y0, y0 + 1]).astype(np.int64), 0, h - 1)
    cols = np.mod(np.stack([x0, x0 + 1]).astype(np.int64), 2 * h)
    top = (1 - fx) * image[rows[0], cols[0]] + fx * image[rows[0], cols[1]]
    bottom = (1 - fx) * image[rows[1], cols[0]] + fx * image[rows[1], cols[1]]
    return (1 - fy) * top + fy * bottom


def read_environment(path, *, exposure: float = 1.0, rotation_deg: float = 0.0) -> EnvironmentMap:
    """An environment map from a Radiance ``.hdr`` or an OpenEXR ``.exr`` file.

    The image must be latitude–longitude (width twice the height), RGB, finite
    and ≥ 0, of at most ``rig.interchange.MAX_IMAGE_PIXELS`` pixels (checked
    from its header before decoding); a :class:`RenderError` names the file and
    what is wrong otherwise.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in _SUFFIXES:
        raise RenderError(f"{path}: an environment map is a .hdr or .exr file")
    if not path.is_file():
        raise RenderError(f"{path}: no such environment map file")
    try:
        check_image_size(path)  # from the header: a damaged one claims any size
    except InterchangeError as err:
        raise RenderError(str(err)) from err
    if suffix == ".hdr":
        try:
            bgr = cv2.imread(str(path), cv2.IMREAD_ANYDEPTH | cv2.IMREAD_COLOR)
        except cv2.error as err:
            raise RenderError(f"{path}: not a readable Radiance HDR image ({err.err})") from err
        if bgr is None:
            raise RenderError(f"{path}: not a readable Radiance HDR image")
        rgb = bgr[..., ::-1]
    else:
        rgb = _read_exr(path)
    try:
        return EnvironmentMap(rgb, exposure=exposure, rotation_deg=rotation_deg, name=str(path))
    except RenderError as err:
        raise RenderError(f"{path}: {err}") from err


def _read_exr(path: Path) -> np.ndarray:
    try:
        with OpenEXR.File(str(path)) as exr:
            channels = exr.channels()
            if "RGB" in channels:
                return np.asarray(channels["RGB"].pixels, np.float32)
            if all(name in channels for name in "RGB"):
                return np.dstack([np.asarray(channels[c].pixels, np.float32) for c in "RGB"])
            found = sorted(channels)
    except Exception as err:  # the bindings raise bare exceptions
        raise RenderError(f"{path}: not a readable OpenEXR image ({err})") from err
    raise RenderError(f"{path}: an environment map needs R, G, B channels; found {found}")


def _cap(vectors: np.ndarray, centre_deg: tuple[float, float], radius_deg: float) -> np.ndarray:
    """(H, W) float64 in [0, 1]: a disc of angular radius ``radius_deg``, its edge as soft as
    a pixel is wide (so a disc smaller than a pixel still lights the pixels it touches)."""
    pixel_deg = 180.0 / vectors.shape[0]
    cosine = vectors @ direction_vector(*centre_deg)
    angle = np.degrees(np.arccos(np.clip(cosine, -1.0, 1.0)))
    return np.clip((radius_deg + pixel_deg - angle) / pixel_deg, 0.0, 1.0)


def synthetic_environment(name: str, *, height: int = 32) -> EnvironmentMap:
    """A small HDR test environment made in code, ``height`` × 2·height pixels.

    ``"sky"``: a blue sky brighter towards the horizon, a sun 3° across of radiance
    3000 (the sky's blue at the zenith is 0.3) at θ = 40°, φ = 120°, dim brown
    ground below the horizon.
    ``"window"``: a dark room (0.02) with a bright window (4.0, θ 50–80°, φ
    60–120°). ``"studio"``: a dark grey studio with a large key softbox, a fill
    softbox opposite and a top light.
    """
    if name not in SYNTHETIC_ENVIRONMENTS:
        raise RenderError(f"environment {name!r}: synthetic ones are {SYNTHETIC_ENVIRONMENTS}")
    if not (isinstance(height, int) and height >= 4):
        raise RenderError(f"height = {height}: need an int ≥ 4")
    vectors, _ = EnvironmentMap(np.zeros((height, 2 * height, 3), np.float32)).pixel_directions()
    up = vectors[..., 2:3]
    if name == "sky":
        horizon = 1.0 - np.clip(up, 0.0, 1.0)
        sky = np.float64([0.25, 0.45, 1.0]) * (0.3 + 0.7 * horizon**2)
        ground = np.float64([0.08, 0.06, 0.04])
        radiance = np.where(up > 0, sky, ground)
        radiance = radiance + 3000.0 * _cap(vectors, (40.0, 120.0), 1.5)[..., None]
    elif name == "window":
        theta, phi = direction_angles(vectors)
        pane = (theta > 50) & (theta < 80) & (phi > 60) & (phi < 120)
        radiance = np.where(pane[..., None], 4.0, 0.02) * np.ones(3)
    else:
        radiance = np.full(vectors.shape, 0.03)
        for centre, radius, level in (((60.0, 300.0), 25.0, 6.0), ((70.0, 120.0), 30.0, 1.5),
                                      ((0.0, 0.0), 15.0, 3.0)):  # fmt: skip
            radiance = radiance + level * _cap(vectors, centre, radius)[..., None]
    return EnvironmentMap(radiance.astype(np.float32), name=name)
