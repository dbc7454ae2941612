"""What `rig view` shows: lights, an environment and the camera from short specs, framing,
exposure.

The specs are checked when parsed, before anything is read or drawn; a bad
one raises ``typer.BadParameter`` naming the option and its valid forms (exit 2).
Angles follow ``rig.geometry``: θ from +z (up), φ the azimuth from +x, degrees.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import typer

__all__ = [
    "CAMERA_FORMS",
    "ENV_FORMS",
    "LIGHT_FORMS",
    "CameraSpec",
    "LightSpec",
    "auto_exposure_ev",
    "mesh_centre",
    "parse_camera",
    "parse_environment",
    "parse_light",
    "parse_size",
    "turned_camera",
]

LIGHT_FORMS = (
    "dir:THETA,PHI[:INTENSITY[:R,G,B]] (a light at infinity, angles in degrees) or "
    "point:X,Y,Z[:IRRADIANCE[:R,G,B]] (a lamp at X,Y,Z mm; IRRADIANCE at the mesh's centre)"
)
CAMERA_FORMS = (
    "orbit:THETA,PHI[,DISTANCE] (from direction θ, φ in degrees, DISTANCE mm; default: the "
    "mesh fills the view) or eye:X,Y,Z (mm, looking at the mesh's centre)"
)
ENV_FORMS = (
    "a latitude–longitude .hdr or .exr file (width twice the height, +z up), or a built-in "
    "test environment: sky (with a sun), window, studio"
)
_MARGIN = 1.1  # the framed outline spans 1 / 1.1 of the image on its tighter side


def _numbers(text: str, counts: tuple[int, ...], option: str, forms: str) -> list[float]:
    try:
        values = [float(part) for part in text.split(",")]
    except ValueError:
        values = []
    if len(values) not in counts or not np.all(np.isfinite(values)):
        raise typer.BadParameter(
            f"{text!r} is not {' or '.join(map(str, counts))} numbers; valid: {forms}",
            param_hint=option,
        )
    return values


def _turn(vector: np.ndarray, turn_deg: float) -> np.ndarray:
    """``vector`` rotated by ``turn_deg`` about +z."""
    c, s = np.cos(np.deg2rad(turn_deg)), np.sin(np.deg2rad(turn_deg))
    return np.array([c * vector[0] - s * vector[1], s * vector[0] + c * vector[1], vector[2]])


def mesh_centre(mesh) -> np.ndarray:
    """The centre of the mesh's bounding box, (3,) float64 mm."""
    positions = np.asarray(mesh.positions, np.float64)
    return (positions.min(axis=0) + positions.max(axis=0)) / 2


@dataclass(frozen=True)
class LightSpec:
    """A light as given on the command line; :meth:`light` places it for a mesh."""

    kind: str  # "dir" or "point"
    where: tuple[float, ...]  # (θ, φ) in degrees, or (x, y, z) in mm
    power: float  # intensity of a directional light, irradiance at the centre of a point light
    colour: tuple[float, float, float]

    def light(self, centre: np.ndarray, turn_deg: float = 0.0):
        """A ``render`` light, carried ``turn_deg`` round the vertical axis through ``centre``;
        a point light's intensity makes ``power`` its irradiance at ``centre``."""
        from render import DirectionalLight, PointLight
        from rig.geometry import direction_vector

        if self.kind == "dir":
            toward = direction_vector(self.where[0], self.where[1] + turn_deg)
            return DirectionalLight(tuple(toward), self.colour, self.power)
        where = centre + _turn(np.asarray(self.where) - centre, turn_deg)
        distance = max(float(np.linalg.norm(where - centre)), 1e-6)
        return PointLight(tuple(where), self.colour, self.power * distance**2)


def parse_light(spec: str) -> LightSpec:
    """``dir:THETA,PHI[:INTENSITY[:R,G,B]]`` or ``point:X,Y,Z[:IRRADIANCE[:R,G,B]]``."""
    kind, _, rest = spec.partition(":")
    parts = rest.split(":")
    if kind not in ("dir", "point") or not rest or len(parts) > 3:
        raise typer.BadParameter(f"{spec!r}: valid: {LIGHT_FORMS}", param_hint="--light")
    where = _numbers(parts[0], (2,) if kind == "dir" else (3,), "--light", LIGHT_FORMS)
    power = _numbers(parts[1], (1,), "--light", LIGHT_FORMS)[0] if len(parts) > 1 else 1.0
    colour = _numbers(parts[2], (3,), "--light", LIGHT_FORMS) if len(parts) > 2 else [1.0] * 3
    from render.lights import MAX_EMISSION

    if power < 0 or min(colour) < 0 or power * max(colour) > MAX_EMISSION:
        raise typer.BadParameter(
            f"{spec!r}: intensity and colour must be ≥ 0, their product at most "
            f"{MAX_EMISSION:.0e}",
            param_hint="--light",
        )
    if kind == "dir" and not 0 <= where[0] <= 180:
        raise typer.BadParameter(f"{spec!r}: THETA must be in 0…180°", param_hint="--light")
    return LightSpec(kind, tuple(where), power, tuple(colour))


@dataclass(frozen=True)
class CameraSpec:
    """A camera as given on the command line; :meth:`camera` frames a mesh with it."""

    kind: str  # "orbit" or "eye"
    values: tuple[float, ...]

    def camera(self, mesh, size: tuple[int, int], fov_deg: float, *, tilt_deg: float = 0.0):
        """A perspective ``render.Camera`` of ``mesh``, raised ``tilt_deg`` towards +z.

        An orbit camera without a distance frames the mesh: it aims at the middle of
        the mesh's outline as seen from (θ, φ) and stands just far enough that every
        vertex is in the image. An eye camera aims at the mesh's centre.
        """
        from render import Camera
        from rig.geometry import direction_vector

        centre = mesh_centre(mesh)
        if self.kind == "orbit":
            theta, phi = self.values[:2]
        else:
            offset = np.asarray(self.values) - centre
            if not np.linalg.norm(offset) > 0:
                raise typer.BadParameter(
                    f"eye {list(self.values)} is the mesh's centre; put the eye outside the mesh",
                    param_hint="--camera",
                )
            theta = np.degrees(np.arccos(np.clip(offset[2] / np.linalg.norm(offset), -1, 1)))
            phi = np.degrees(np.arctan2(offset[1], offset[0]))
        toward_eye = direction_vector(float(np.clip(theta - tilt_deg, 0.0, 180.0)), phi)
        if self.kind == "eye":
            eye = centre + np.linalg.norm(np.asarray(self.values) - centre) * toward_eye
            return Camera.perspective(eye, centre, fov_deg=fov_deg, size=size)
        target, distance = _frame(np.asarray(mesh.positions, np.float64), toward_eye, size, fov_deg)
        if len(self.values) > 2:
            distance = self.values[2]
        return Camera.perspective(
            target + distance * toward_eye, target, fov_deg=fov_deg, size=size
        )


def _frame(
    positions: np.ndarray, toward_eye: np.ndarray, size: tuple[int, int], fov_deg: float
) -> tuple[np.ndarray, float]:
    """Target and distance that centre the mesh's outline and fit every vertex in the image.

    The line of sight stays along −``toward_eye``; the eye slides across it to centre
    the perspective outline and backs off until every vertex is inside, with a margin.
    """
    forward = -toward_eye
    right = np.cross(forward, [0.0, 0.0, 1.0])
    if np.linalg.norm(right) < 1e-6:  # looking straight up or down: +y is up in the image
        right = np.cross(forward, [0.0, 1.0, 0.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    centre = (positions.min(axis=0) + positions.max(axis=0)) / 2
    relative = positions - centre
    offsets = np.stack([relative @ right, relative @ up])  # (2, V): across and upward
    nearer = relative @ toward_eye
    half_tan = np.tan(np.deg2rad(fov_deg) / 2) * np.array([size[0] / size[1], 1.0]) / _MARGIN
    shift = (offsets.max(axis=1) + offsets.min(axis=1)) / 2
    distance = 0.0
    for _ in range(6):  # alternate: the distance that fits, the shift that centres at it
        distance = float(np.max(np.abs(offsets - shift[:, None]) / half_tan[:, None] + nearer))
        depth = np.maximum(distance - nearer, 1e-9)
        shift = np.array([_centring_shift(o, depth) for o in offsets])
    distance = float(np.max(np.abs(offsets - shift[:, None]) / half_tan[:, None] + nearer))
    return centre + shift[0] * right + shift[1] * up, max(distance, 1e-3)


def _centring_shift(offset: np.ndarray, depth: np.ndarray) -> float:
    """The shift s that makes the image of ``(offset − s) / depth`` symmetric about 0.

    max + min of the projected positions falls as s grows: bisection finds its zero.
    """
    low, high = float(offset.min()), float(offset.max())
    for _ in range(50):
        middle = (low + high) / 2
        projected = (offset - middle) / depth
        if projected.max() + projected.min() > 0:
            low = middle
        else:
            high = middle
    return (low + high) / 2


def turned_camera(camera, centre: np.ndarray, turn_deg: float):
    """``camera`` carried ``turn_deg`` round the vertical axis through ``centre``."""
    from render import Camera

    eye = centre + _turn(camera.eye - centre, turn_deg)
    target = centre + _turn(camera.target - centre, turn_deg)
    return Camera.perspective(eye, target, fov_deg=camera.fov_deg, size=camera.size)


def parse_camera(spec: str) -> CameraSpec:
    """``orbit:THETA,PHI[,DISTANCE]`` or ``eye:X,Y,Z``."""
    kind, _, rest = spec.partition(":")
    if kind not in ("orbit", "eye") or not rest:
        raise typer.BadParameter(f"{spec!r}: valid: {CAMERA_FORMS}", param_hint="--camera")
    values = _numbers(rest, (2, 3) if kind == "orbit" else (3,), "--camera", CAMERA_FORMS)
    if kind == "orbit" and (not 0 <= values[0] <= 180 or (len(values) == 3 and values[2] <= 0)):
        raise typer.BadParameter(
            f"{spec!r}: THETA must be in 0…180° and DISTANCE > 0 mm", param_hint="--camera"
        )
    return CameraSpec(kind, tuple(values))


def parse_size(spec: str) -> tuple[int, int]:
    """``WxH`` in pixels, each 1…16384."""
    width, _, height = spec.lower().partition("x")
    if not (width.isdigit() and height.isdigit()) or not (
        0 < int(width) <= 16384 and 0 < int(height) <= 16384
    ):
        raise typer.BadParameter(
            f"{spec!r}: expected WxH such as 640x480, each 1…16384 pixels", param_hint="--size"
        )
    return int(width), int(height)


def auto_exposure_ev(image: np.ndarray) -> float:
    """The exposure (EV) that puts the 99th percentile of the lit surface's brightest channel
    at 90 % white; 0 when nothing is lit.

    A material's radiance is in its own units (relative radiance per second of
    exposure, say), so one fixed exposure would suit one material and blind the next.
    """
    lit = np.asarray(image, np.float64).max(axis=-1)
    lit = lit[np.isfinite(lit) & (lit > 0)]
    if lit.size == 0:
        return 0.0
    return float(np.log2(0.9 / np.percentile(lit, 99)))


def parse_environment(spec: str, rotate_deg: float):
    """The :class:`render.EnvironmentMap` ``spec`` names (a file or a built-in), turned by
    ``rotate_deg`` about +z; a file that cannot be read or is not latitude–longitude is a
    ``typer.BadParameter`` naming it."""
    from render import RenderError, read_environment, synthetic_environment
    from render.environment import SYNTHETIC_ENVIRONMENTS

    try:
        if spec in SYNTHETIC_ENVIRONMENTS:
            return synthetic_environment(spec, height=64).with_view(rotation_deg=rotate_deg)
        return read_environment(spec, rotation_deg=rotate_deg)
    except RenderError as err:
        raise typer.BadParameter(f"{err}; valid: {ENV_FORMS}", param_hint="--env") from err
