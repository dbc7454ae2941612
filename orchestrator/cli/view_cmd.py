"""`rig view`: a measured material on a mesh — a PNG or EXR, a turntable GIF, or a window."""

from __future__ import annotations

from contextlib import ExitStack
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated

import numpy as np
import typer

from orchestrator.cli.common import console, prepare_file, working
from orchestrator.cli.view_scene import (
    CAMERA_FORMS,
    ENV_FORMS,
    LIGHT_FORMS,
    CameraSpec,
    LightSpec,
    auto_exposure_ev,
    mesh_centre,
    parse_camera,
    parse_environment,
    parse_light,
    parse_size,
    turned_camera,
)
from rig.errors import ConfigError, RigError

__all__ = ["ViewOptions", "register", "view"]

_OUT_SUFFIXES = (".png", ".exr")
_DEFAULT_LIGHT = "dir:40,-130"
_GIF_FRAME_MS = 80
#: --exposure range, stops: 2^±64 spans any radiance a float32 image holds
_MAX_EXPOSURE_EV = 64.0


@dataclass(frozen=True)
class ViewOptions:
    """What `rig view` draws, parsed and checked once from its options.

    ``environment`` is a ``render.EnvironmentMap`` or None (lamps only), drawn by
    ``env_method`` (visibility, pca or pem) with ``vis_res`` hemicubes or ``median_cut``
    lights; ``lights`` are the lamps, under an environment only those given; ``size``
    is (width, height) in pixels; ``tile_mm`` None draws the sample at true scale;
    ``mdf`` None uses the MDF when the material holds one; ``exposure_ev`` None picks
    one from the first image; the image goes to ``out``, a GIF of ``turntable`` frames,
    or a ``window``.
    """

    material: Path
    mesh: str
    environment: object | None
    env_method: str
    vis_res: int
    median_cut: int
    lights: tuple[LightSpec, ...]
    camera: CameraSpec
    fov_deg: float
    size: tuple[int, int]
    tile_mm: float | None
    mdf: bool | None
    peel: int
    pbr: bool
    exposure_ev: float | None
    out: Path | None
    turntable: int | None
    window: bool

    @property
    def through_maps(self) -> bool:
        """Whether the environment is drawn through visibility maps (not median-cut lights)."""
        return self.environment is not None and self.env_method != "pem"


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
            "nothing to do: give --out FILE.png|FILE.exr, --turntable N --out FILE.gif, "
            "or --window",
            param_hint="--out",
        )
    if out is not None:
        prepare_file(out, "--out")  # before anything is read or drawn


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
            "OBJ/PLY/glTF/GLB file with UVs (OBJ, PLY in mm; glTF in metres, +Y up, "
            "as it defines)"
        ),
    ] = "cloth",
    light: Annotated[
        list[str] | None,
        typer.Option(
            metavar="<str>", help=f"a light, repeatable (default {_DEFAULT_LIGHT}): {LIGHT_FORMS}"
        ),
    ] = None,
    camera: Annotated[str, typer.Option(help=CAMERA_FORMS)] = "orbit:60,-90",
    fov_deg: Annotated[
        float, typer.Option("--fov", min=1.0, max=170.0, help="vertical field of view, degrees")
    ] = 30.0,
    size: Annotated[
        str,
        typer.Option(
            help="image size WxH in pixels, each 1…16384 and within what the OpenGL context draws"
        ),
    ] = "640x480",
    tile_mm: Annotated[
        float | None,
        typer.Option(
            min=1e-3,
            help="mm of surface one repeat of the sample covers "
            "(default: the sample's measured side, true scale)",
        ),
    ] = None,
    exposure: Annotated[
        float | None,
        typer.Option(
            help="exposure in EV (stops) for the sRGB PNG/GIF (the EXR stays linear); "
            "default: the brightest 1 % of the first frame's surface at 90 % white"
        ),
    ] = None,
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
            "shift-drag to turn the lights, wheel for exposure",
        ),
    ] = False,
    env: Annotated[
        str | None,
        typer.Option(help=f"light by an environment (--light adds lamps on top): {ENV_FORMS}"),
    ] = None,
    env_rotate: Annotated[
        float, typer.Option(help="turn the environment about the vertical axis, degrees")
    ] = 0.0,
    env_method: Annotated[
        str,
        typer.Option(
            help="visibility (a new pass over every visibility map per environment or turn), "
            "pca (the PCA of 30 turns: turning is fast) or pem (median-cut regions as "
            "extended lights with soft shadows: any material)"
        ),
    ] = "visibility",
    vis_res: Annotated[
        int,
        typer.Option(
            min=2,
            max=64,
            help="hemicube resolution n of the visibility maps (even; 3n² rays per "
            "vertex); 8 is a faster preview, its sun's light patchier",
        ),
    ] = 16,  # render.environment.visibility.DEFAULT_RESOLUTION (imported only to draw)
    median_cut: Annotated[
        int, typer.Option(min=1, max=1024, help="lights of --env-method pem (a power of 2)")
    ] = 16,
    mdf: Annotated[
        bool | None,
        typer.Option(
            "--mdf/--no-mdf",
            help="mesostructure silhouettes (depth peeling) and shadows (the ambient term "
            "where shadowed) from the material's MDF (default: when the material holds one)",
        ),
    ] = None,
    peel: Annotated[int, typer.Option(min=1, max=8, help="depth-peeling passes with the MDF")] = 2,
    pbr: Annotated[
        bool,
        typer.Option(
            "--pbr",
            help="draw the material's PBR fit (rig process --stages pbr) instead of its BTF "
            "and PS maps, without the MDF; point and directional lights only",
        ),
    ] = False,
) -> None:
    """Render a material on a mesh under lights or an environment.

    Draws a PNG or EXR image, a turntable GIF, or an interactive window, under
    point and directional lights (--light), an environment map (--env), or both.
    """
    if env_method not in ("visibility", "pca", "pem"):
        raise typer.BadParameter(
            f"{env_method!r}: valid are visibility, pca, pem", param_hint="--env-method"
        )
    if median_cut & (median_cut - 1):
        raise typer.BadParameter(f"{median_cut} is not a power of 2", param_hint="--median-cut")
    if vis_res % 2:
        raise typer.BadParameter(f"{vis_res} is odd; give an even n", param_hint="--vis-res")
    if exposure is not None and not abs(exposure) <= _MAX_EXPOSURE_EV:  # NaN too
        raise typer.BadParameter(
            f"{exposure}: give stops in -{_MAX_EXPOSURE_EV:g}…{_MAX_EXPOSURE_EV:g}",
            param_hint="--exposure",
        )
    if mdf and env is not None and env_method != "pem":
        raise typer.BadParameter(
            f"--env-method {env_method} draws no MDF silhouettes; use --env-method pem or --no-mdf",
            param_hint="--mdf",
        )
    if pbr and (env is not None or mdf):
        raise typer.BadParameter(
            "the PBR fit draws under point and directional lights, without the MDF; "
            "leave out --env and --mdf",
            param_hint="--pbr",
        )
    options = ViewOptions(
        material=material,
        mesh=mesh,
        environment=None if env is None else parse_environment(env, env_rotate),
        env_method=env_method,
        vis_res=vis_res,
        median_cut=median_cut,
        # Under an environment, lights are only those given (added to its light).
        lights=tuple(parse_light(s) for s in light or ([] if env else [_DEFAULT_LIGHT])),
        camera=parse_camera(camera),
        fov_deg=fov_deg,
        size=parse_size(size),
        tile_mm=tile_mm,
        mdf=mdf,
        peel=peel,
        pbr=pbr,
        exposure_ev=exposure,
        out=out,
        turntable=turntable,
        window=window,
    )
    _check_out(out, turntable, window)
    if window:
        from render.window import require_display

        require_display()  # before the material and the mesh are read
    _render(options)


def _render(options: ViewOptions) -> None:
    """Draw ``options``' image, turntable or window."""
    from render import RenderError
    from render.meshes import MeshError, mesh_by_name
    from render.output import to_srgb8, write_exr, write_png
    from rig.material import MaterialError, read_material

    try:
        material = read_material(options.material)
        mesh = mesh_by_name(options.mesh)
    except (MaterialError, MeshError) as err:
        raise ConfigError(str(err)) from err
    size, out, turntable = options.size, options.out, options.turntable
    with ExitStack() as stack:
        draw = _drawing(options, material, mesh, stack)
        try:
            first = draw(0.0, 0.0, 0.0)
        except RenderError as err:  # asked more than this context draws (--size, a lamp)
            raise ConfigError(str(err)) from err
        exposure_ev = (
            auto_exposure_ev(first) if options.exposure_ev is None else options.exposure_ev
        )
        if options.window:
            from render.window import open_window

            title = f"rig view {options.material}"
            open_window(draw, size=size, exposure_ev=exposure_ev, title=title)
            return
        out.parent.mkdir(parents=True, exist_ok=True)
        if turntable is None:
            if out.suffix.lower() == ".exr":
                write_exr(out, first)
            else:
                write_png(out, first, exposure_ev=exposure_ev)
            environment = options.environment
            lit_by = ", ".join(
                ([environment.name] if environment is not None else [])
                + ([f"{len(options.lights)} light(s)"] if options.lights else [])
            )
            console.print(
                f"wrote {out} ({size[0]}×{size[1]}, {mesh.name}, {lit_by}, "
                f"exposure {exposure_ev:+.2f} EV)"
            )
            return
        # A turntable turns the sample under the rig: camera and lights go round together.
        turns = np.arange(1, turntable) * 360.0 / turntable
        frames = [first]
        with working(f"rendering {out}", total=turntable) as advance:
            advance()
            for turn in turns:
                frames.append(draw(turn, 0.0, turn))
                advance()
    _write_gif(out, [to_srgb8(frame, exposure_ev=exposure_ev) for frame in frames])
    console.print(f"wrote {out} ({turntable} frames, {size[0]}×{size[1]}, {mesh.name})")


def _drawing(options: ViewOptions, material, mesh, stack: ExitStack):
    """``draw(turn_deg, tilt_deg, light_turn_deg)``: the image (H, W, 3) float32 linear
    with the camera turned and raised and the lights turned (degrees); its renderers
    are entered on ``stack``."""
    from render import EnvironmentRenderer, PemRenderer, Renderer, RenderError

    spec, size, fov_deg = options.camera, options.size, options.fov_deg
    framed = spec.camera(mesh, size, fov_deg)
    centre = mesh_centre(mesh)
    environment, through_maps = options.environment, options.through_maps
    lit = None
    if through_maps:
        try:
            lit = EnvironmentRenderer(
                material, mesh, tile_mm=options.tile_mm, method=options.env_method,
                resolution=options.vis_res,
            )  # fmt: skip
        except RenderError as err:  # a material the environment path cannot draw
            raise ConfigError(str(err)) from err
        stack.enter_context(lit)
    renderer = None
    if options.lights or not through_maps:
        # Lamps added to the environment maps' image draw no MDF: the outlines must agree.
        mdf, peel = (False, 1) if through_maps else (options.mdf, options.peel)
        kind = Renderer if through_maps or environment is None else PemRenderer
        # Under an environment its own light fills the shadows: no ambient term on top.
        fill = {} if environment is None else {"ambient": 0.0}
        layers = ("pbr",) if options.pbr else None
        try:
            made = kind(material, mesh, tile_mm=options.tile_mm, mdf=mdf, peel=peel,
                        layers=layers, **fill)  # fmt: skip
        except RenderError as err:  # --mdf on a material without one
            raise ConfigError(str(err)) from err
        renderer = stack.enter_context(made)

    def draw(turn_deg: float, tilt_deg: float, light_turn_deg: float) -> np.ndarray:
        raised = framed if tilt_deg == 0 else spec.camera(mesh, size, fov_deg, tilt_deg=tilt_deg)
        camera = turned_camera(raised, centre, turn_deg)
        placed = [light.light(centre, light_turn_deg) for light in options.lights]
        if environment is None:
            return renderer.render(camera, placed)
        # Light adds up: the environment's image plus the lights' image.
        turned = environment.with_view(rotation_deg=environment.rotation_deg + light_turn_deg)
        if not through_maps:
            return renderer.render_environment(
                camera, turned, count=options.median_cut, lights=placed
            )
        image = lit.render(camera, turned)
        return image + renderer.render(camera, placed) if placed else image

    return draw


def _write_gif(path: Path, frames: list[np.ndarray]) -> None:
    from PIL import Image

    images = [Image.fromarray(frame) for frame in frames]
    try:
        images[0].save(
            path, save_all=True, append_images=images[1:], duration=_GIF_FRAME_MS, loop=0
        )
    except OSError as err:
        raise RigError(f"{path}: cannot write the animation ({err})") from err


def register(app: typer.Typer) -> None:
    """Add `rig view` to ``app``."""
    app.command()(view)
