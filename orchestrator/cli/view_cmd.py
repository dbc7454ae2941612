"""`rig view`: a measured material on a mesh — a PNG or EXR, a turntable GIF, or a window.

Lights and the camera are given as short specs (``dir:45,30``,
``orbit:55,-90``); they are checked before anything is read or drawn, and a
bad one exits 2 naming the option and its valid forms.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Annotated

import numpy as np
import typer

from orchestrator.cli.common import (
    EXIT_INVALID,
    console,
    err_console,
    reporting_errors,
)
from rig.errors import RigError

__all__ = ["CameraSpec", "LightSpec", "parse_camera", "parse_light", "parse_size", "register"]

LIGHT_FORMS = (
    "dir:THETA,PHI[:INTENSITY[:R,G,B]] (a light at infinity, angles in degrees) or "
    "point:X,Y,Z[:IRRADIANCE[:R,G,B]] (a lamp at X,Y,Z mm; IRRADIANCE at the mesh's centre)"
)
CAMERA_FORMS = (
    "orbit:THETA,PHI[,DISTANCE] (from direction θ, φ in degrees about the mesh's centre, "
    "DISTANCE mm, default: the mesh fills the view) or eye:X,Y,Z (mm, looking at the centre)"
)
_OUT_SUFFIXES = (".png", ".exr")


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


@dataclass(frozen=True)
class LightSpec:
    """A light as given on the command line; :meth:`light` places it for a mesh."""

    kind: str  # "dir" or "point"
    where: tuple[float, ...]  # (θ, φ) in degrees, or (x, y, z) in mm
    power: float  # intensity of a directional light, irradiance at the centre of a point light
    colour: tuple[float, float, float]

    def light(self, centre: np.ndarray):
        """A ``render`` light; a point light gets ``power`` as its irradiance at ``centre``."""
        from render import DirectionalLight, PointLight
        from rig.geometry import direction_vector

        if self.kind == "dir":
            return DirectionalLight(tuple(direction_vector(*self.where)), self.colour, self.power)
        distance = float(np.linalg.norm(np.asarray(self.where) - centre))
        return PointLight(self.where, self.colour, self.power * max(distance, 1e-6) ** 2)


def parse_light(spec: str) -> LightSpec:
    """``dir:THETA,PHI[:INTENSITY[:R,G,B]]`` or ``point:X,Y,Z[:IRRADIANCE[:R,G,B]]``."""
    kind, _, rest = spec.partition(":")
    parts = rest.split(":")
    if kind not in ("dir", "point") or not rest or len(parts) > 3:
        raise typer.BadParameter(f"{spec!r}: valid: {LIGHT_FORMS}", param_hint="--light")
    where = _numbers(parts[0], (2,) if kind == "dir" else (3,), "--light", LIGHT_FORMS)
    power = _numbers(parts[1], (1,), "--light", LIGHT_FORMS)[0] if len(parts) > 1 else 1.0
    colour = _numbers(parts[2], (3,), "--light", LIGHT_FORMS) if len(parts) > 2 else [1.0] * 3
    if power < 0 or min(colour) < 0:
        raise typer.BadParameter(
            f"{spec!r}: intensity and colour must be ≥ 0", param_hint="--light"
        )
    if kind == "dir" and not 0 <= where[0] <= 180:
        raise typer.BadParameter(f"{spec!r}: THETA must be in 0…180°", param_hint="--light")
    return LightSpec(kind, tuple(where), power, tuple(colour))


@dataclass(frozen=True)
class CameraSpec:
    """A camera as given on the command line; :meth:`camera` places it for a mesh."""

    kind: str  # "orbit" or "eye"
    values: tuple[float, ...]

    def camera(
        self,
        centre: np.ndarray,
        radius: float,
        size: tuple[int, int],
        fov_deg: float,
        *,
        turn_deg: float = 0.0,
        tilt_deg: float = 0.0,
    ):
        """A perspective ``render.Camera`` looking at ``centre`` (the mesh's, of ``radius`` mm).

        ``turn_deg`` carries the eye round the vertical axis, ``tilt_deg`` raises it.
        """
        from render import Camera
        from rig.geometry import direction_vector

        if self.kind == "orbit":
            theta, phi = self.values[:2]
            # Far enough that the bounding sphere fits the narrower of the two fields of view.
            narrow = np.deg2rad(min(fov_deg, fov_deg * size[0] / size[1]))
            distance = self.values[2] if len(self.values) > 2 else radius / np.sin(narrow / 2)
        else:
            offset = np.asarray(self.values) - centre
            distance = float(np.linalg.norm(offset))
            theta = np.degrees(np.arccos(np.clip(offset[2] / max(distance, 1e-12), -1.0, 1.0)))
            phi = np.degrees(np.arctan2(offset[1], offset[0]))
        theta = float(np.clip(theta - tilt_deg, 0.0, 180.0))
        eye = centre + distance * direction_vector(theta, phi + turn_deg)
        return Camera.perspective(eye, centre, fov_deg=fov_deg, size=size)


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
    if not (
        width.isdigit()
        and height.isdigit()
        and 0 < int(width) <= 16384
        and 0 < int(height) <= 16384
    ):
        raise typer.BadParameter(
            f"{spec!r}: expected WxH such as 640x480, each 1…16384 pixels", param_hint="--size"
        )
    return int(width), int(height)


def _turn(vector: np.ndarray, turn_deg: float) -> np.ndarray:
    """``vector`` rotated by ``turn_deg`` about +z."""
    c, s = np.cos(np.deg2rad(turn_deg)), np.sin(np.deg2rad(turn_deg))
    return np.array([c * vector[0] - s * vector[1], s * vector[0] + c * vector[1], vector[2]])


def _turned(spec: LightSpec, centre: np.ndarray, turn_deg: float) -> LightSpec:
    """The light carried round with the camera: a turntable turns the sample, not the rig."""
    if spec.kind == "dir":
        return LightSpec("dir", (spec.where[0], spec.where[1] + turn_deg), spec.power, spec.colour)
    where = centre + _turn(np.asarray(spec.where) - centre, turn_deg)
    return LightSpec("point", tuple(where), spec.power, spec.colour)


def _check_out(out: Path | None, turntable: int | None, window: bool) -> None:
    if turntable is not None and (out is None or out.suffix.lower() != ".gif"):
        raise typer.BadParameter(
            f"--turntable writes an animated GIF: give --out FILE.gif (got {out})",
            param_hint="--out",
        )
    if turntable is None and out is not None and out.suffix.lower() not in _OUT_SUFFIXES:
        raise typer.BadParameter(
            f"{out}: write a .png (sRGB, 8-bit) or an .exr (linear float); "
            ".gif needs --turntable N",
            param_hint="--out",
        )
    if out is None and not window:
        raise typer.BadParameter(
            "nothing to do: give --out FILE.png|FILE.exr, "
            "--turntable N --out FILE.gif, or --window",
            param_hint="--out",
        )


def register(app: typer.Typer) -> None:
    @app.command()
    def view(
        material: Annotated[
            Path,
            typer.Argument(
                help="a session archive with a material/ group, or a material store "
                "(rig export material)"
            ),
        ],
        mesh: Annotated[
            str,
            typer.Option(
                help="plane | sphere | cylinder | torus | cloth (draped over a sphere), or an "
                "OBJ/PLY/glTF/GLB file with UVs"
            ),
        ] = "cloth",
        light: Annotated[
            list[str] | None,
            typer.Option(help=f"a light, repeatable (default dir:40,-60): {LIGHT_FORMS}"),
        ] = None,
        camera: Annotated[str, typer.Option(help=CAMERA_FORMS)] = "orbit:55,-90",
        fov_deg: Annotated[
            float, typer.Option("--fov", min=1.0, max=170.0, help="vertical field of view, degrees")
        ] = 35.0,
        size: Annotated[str, typer.Option(help="image size WxH in pixels")] = "640x480",
        tile_mm: Annotated[
            float | None,
            typer.Option(
                min=1e-3,
                help="mm of surface one repeat of the sample covers "
                "(default: the sample's measured side, true scale)",
            ),
        ] = None,
        exposure: Annotated[
            float,
            typer.Option(
                help="exposure in EV (stops) applied before the sRGB PNG/GIF; EXR stays linear"
            ),
        ] = 0.0,
        out: Annotated[
            Path | None,
            typer.Option(
                help="write the image: .png (sRGB) or .exr (linear float); .gif with --turntable"
            ),
        ] = None,
        turntable: Annotated[
            int | None,
            typer.Option(
                min=2, max=720, help="write an animated GIF of N frames, the sample turning once"
            ),
        ] = None,
        window: Annotated[
            bool,
            typer.Option(
                "--window",
                help="open an interactive viewer (needs a display): drag to orbit, "
                "shift-drag to move the light",
            ),
        ] = False,
    ) -> None:
        """Render a material on a mesh under point and directional lights."""
        lights = [parse_light(s) for s in light or ["dir:40,-60"]]
        camera_spec = parse_camera(camera)
        image_size = parse_size(size)
        _check_out(out, turntable, window)
        if window:
            from render.window import require_display

            with reporting_errors():
                require_display()  # before the material and the mesh are read
        with reporting_errors():
            _run(
                material,
                mesh,
                lights,
                camera_spec,
                fov_deg,
                image_size,
                tile_mm,
                exposure,
                out,
                turntable,
                window,
            )


def _run(
    material_path,
    mesh_name,
    lights,
    camera_spec,
    fov_deg,
    size,
    tile_mm,
    exposure,
    out,
    turntable,
    window,
) -> None:
    from render import Renderer
    from render.meshes import MeshError, mesh_by_name
    from render.output import to_srgb8, write_exr, write_png
    from rig.material import MaterialError, read_material

    try:
        material = read_material(material_path)
        mesh = mesh_by_name(mesh_name)
    except (MaterialError, MeshError) as err:
        err_console.print(f"[red]error:[/red] {err}")
        raise typer.Exit(EXIT_INVALID) from err
    positions = np.asarray(mesh.positions, np.float64)
    centre = (positions.min(axis=0) + positions.max(axis=0)) / 2
    radius = float(np.linalg.norm(positions - centre, axis=1).max())
    with Renderer(material, mesh, tile_mm=tile_mm) as renderer:
        if window:
            from render.window import open_window

            def draw(turn_deg: float, tilt_deg: float, light_turn_deg: float) -> np.ndarray:
                placed = [_turned(spec, centre, light_turn_deg).light(centre) for spec in lights]
                view = camera_spec.camera(
                    centre, radius, size, fov_deg, turn_deg=turn_deg, tilt_deg=tilt_deg
                )
                return renderer.render(view, placed)

            open_window(draw, size=size, exposure_ev=exposure, title=f"rig view {material_path}")
            return
        if turntable is None:
            image = renderer.render(
                camera_spec.camera(centre, radius, size, fov_deg),
                [spec.light(centre) for spec in lights],
            )
            out.parent.mkdir(parents=True, exist_ok=True)
            if out.suffix.lower() == ".exr":
                write_exr(out, image)
            else:
                write_png(out, image, exposure_ev=exposure)
            console.print(f"wrote {out} ({size[0]}×{size[1]}, {mesh.name}, {len(lights)} light(s))")
            return
        frames = []
        for turn in np.arange(turntable) * 360.0 / turntable:
            placed = [_turned(spec, centre, turn).light(centre) for spec in lights]
            image = renderer.render(
                camera_spec.camera(centre, radius, size, fov_deg, turn_deg=turn), placed
            )
            frames.append(to_srgb8(image, exposure_ev=exposure))
    _write_gif(out, frames)
    console.print(f"wrote {out} ({turntable} frames, {size[0]}×{size[1]}, {mesh.name})")


def _write_gif(path: Path, frames: list[np.ndarray]) -> None:
    from PIL import Image

    images = [Image.fromarray(frame) for frame in frames]
    path.parent.mkdir(parents=True, exist_ok=True)
    try:
        images[0].save(path, save_all=True, append_images=images[1:], duration=80, loop=0)
    except OSError as err:
        raise RigError(f"{path}: cannot write the animation ({err})") from err
