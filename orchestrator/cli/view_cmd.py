"""`rig view`: a measured material on a mesh — a PNG or EXR, a turntable GIF, or a window."""

from __future__ import annotations

from contextlib import ExitStack
from pathlib import Path
from typing import Annotated

import numpy as np
import typer

from orchestrator.cli.common import EXIT_INVALID, console, err_console, prepare_file, working
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
from rig.errors import RigError

__all__ = ["register"]

_OUT_SUFFIXES = (".png", ".exr")
_DEFAULT_LIGHT = "dir:40,-130"
_GIF_FRAME_MS = 80
#: --exposure range, stops: 2^±64 spans any radiance a float32 image holds
_MAX_EXPOSURE_EV = 64.0


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
                "OBJ/PLY/glTF/GLB file with UVs (OBJ, PLY in mm; glTF in metres, +Y up, "
                "as it defines)"
            ),
        ] = "cloth",
        light: Annotated[
            list[str] | None,
            typer.Option(help=f"a light, repeatable (default {_DEFAULT_LIGHT}): {LIGHT_FORMS}"),
        ] = None,
        camera: Annotated[str, typer.Option(help=CAMERA_FORMS)] = "orbit:60,-90",
        fov_deg: Annotated[
            float, typer.Option("--fov", min=1.0, max=170.0, help="vertical field of view, degrees")
        ] = 30.0,
        size: Annotated[
            str,
            typer.Option(
                help="image size WxH in pixels, each 1…16384 and within what the OpenGL "
                "context draws"
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
        peel: Annotated[
            int, typer.Option(min=1, max=8, help="depth-peeling passes with the MDF")
        ] = 2,
        pbr: Annotated[
            bool,
            typer.Option(
                "--pbr",
                help="draw the material's PBR fit (rig process --stages pbr) instead of its BTF "
                "and PS maps, without the MDF; point and directional lights only",
            ),
        ] = False,
    ) -> None:
        """Render a material on a mesh under point and directional lights or an environment."""
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
                f"--env-method {env_method} draws no MDF silhouettes; use --env-method pem "
                "or --no-mdf",
                param_hint="--mdf",
            )
        if pbr and (env is not None or mdf):
            raise typer.BadParameter(
                "the PBR fit draws under point and directional lights, without the MDF; "
                "leave out --env and --mdf",
                param_hint="--pbr",
            )
        environment = None if env is None else parse_environment(env, env_rotate)
        lighting = environment, env_method, vis_res, median_cut
        # Under an environment, lights are only those given (added to its light).
        lights = [parse_light(s) for s in light or ([] if env else [_DEFAULT_LIGHT])]
        camera_spec = parse_camera(camera)
        image_size = parse_size(size)
        _check_out(out, turntable, window)
        if window:
            from render.window import require_display

            require_display()  # before the material and the mesh are read
        _run(
            material, mesh, lights, camera_spec, fov_deg, image_size, tile_mm, exposure,
            out, turntable, window, lighting, (mdf, peel), ("pbr",) if pbr else None,
        )  # fmt: skip


def _run(
    material_path: Path,
    mesh_name: str,
    lights: list[LightSpec],
    camera_spec: CameraSpec,
    fov_deg: float,
    size: tuple[int, int],
    tile_mm: float | None,
    exposure: float | None,
    out: Path | None,
    turntable: int | None,
    window: bool,
    lighting: tuple,
    silhouettes: tuple[bool | None, int],
    layers: tuple[str, ...] | None = None,
) -> None:
    from render import EnvironmentRenderer, PemRenderer, Renderer, RenderError
    from render.meshes import MeshError, mesh_by_name
    from render.output import to_srgb8, write_exr, write_png
    from rig.material import MaterialError, read_material

    try:
        material = read_material(material_path)
        mesh = mesh_by_name(mesh_name)
    except (MaterialError, MeshError) as err:
        err_console.print(f"[red]error:[/red] {err}")
        raise typer.Exit(EXIT_INVALID) from err
    centre = mesh_centre(mesh)
    framed = camera_spec.camera(mesh, size, fov_deg)
    environment, env_method, vis_res, median_cut = lighting
    through_maps = environment is not None and env_method != "pem"
    try:
        lit = (
            EnvironmentRenderer(
                material, mesh, tile_mm=tile_mm, method=env_method, resolution=vis_res
            )
            if through_maps
            else None
        )
    except RenderError as err:  # a material the environment path cannot draw
        err_console.print(f"[red]error:[/red] {err}")
        raise typer.Exit(EXIT_INVALID) from err
    with ExitStack() as stack:
        if lit is not None:
            stack.enter_context(lit)
        renderer = None
        if lights or not through_maps:
            # Lamps added to the environment maps' image draw no MDF: the outlines must agree.
            mdf, peel = (False, 1) if through_maps else silhouettes
            kind = Renderer if through_maps or environment is None else PemRenderer
            try:
                # Under an environment its own light fills the shadows: no ambient term on top.
                fill = {} if environment is None else {"ambient": 0.0}
                made = kind(material, mesh, tile_mm=tile_mm, mdf=mdf, peel=peel, layers=layers,
                            **fill)  # fmt: skip
            except RenderError as err:  # --mdf on a material without one
                err_console.print(f"[red]error:[/red] {err}")
                raise typer.Exit(EXIT_INVALID) from err
            renderer = stack.enter_context(made)

        def draw(turn_deg: float, tilt_deg: float, light_turn_deg: float) -> np.ndarray:
            """The image with the camera turned and raised, the lights turned (degrees)."""
            view = (
                framed
                if tilt_deg == 0
                else camera_spec.camera(mesh, size, fov_deg, tilt_deg=tilt_deg)
            )
            camera = turned_camera(view, centre, turn_deg)
            placed = [spec.light(centre, light_turn_deg) for spec in lights]
            if environment is None:
                return renderer.render(camera, placed)
            # Light adds up: the environment's image plus the lights' image.
            turned = environment.with_view(rotation_deg=environment.rotation_deg + light_turn_deg)
            if not through_maps:
                return renderer.render_environment(camera, turned, count=median_cut, lights=placed)
            image = lit.render(camera, turned)
            return image + renderer.render(camera, placed) if placed else image

        try:
            first = draw(0.0, 0.0, 0.0)
        except RenderError as err:  # asked more than this context draws (--size, a lamp)
            err_console.print(f"[red]error:[/red] {err}")
            raise typer.Exit(EXIT_INVALID) from err
        exposure_ev = auto_exposure_ev(first) if exposure is None else exposure
        if window:
            from render.window import open_window

            open_window(draw, size=size, exposure_ev=exposure_ev, title=f"rig view {material_path}")
            return
        out.parent.mkdir(parents=True, exist_ok=True)
        if turntable is None:
            if out.suffix.lower() == ".exr":
                write_exr(out, first)
            else:
                write_png(out, first, exposure_ev=exposure_ev)
            lit_by = ", ".join(
                ([environment.name] if environment is not None else [])
                + ([f"{len(lights)} light(s)"] if lights else [])
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


def _write_gif(path: Path, frames: list[np.ndarray]) -> None:
    from PIL import Image

    images = [Image.fromarray(frame) for frame in frames]
    try:
        images[0].save(
            path, save_all=True, append_images=images[1:], duration=_GIF_FRAME_MS, loop=0
        )
    except OSError as err:
        raise RigError(f"{path}: cannot write the animation ({err})") from err
