"""`rig view`: images, EXR, turntable GIF from a small material store; exit codes for bad input."""

import importlib.util
import json
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import numpy as np
import OpenEXR
import pytest
import trimesh
from numpy.testing import assert_allclose
from PIL import Image
from typer.testing import CliRunner

from orchestrator.cli import app
from orchestrator.cli.view_scene import mesh_centre, parse_camera, parse_light
from render.meshes import mesh_by_name

runner = CliRunner()


def _view(store, *args):
    return runner.invoke(app, ["view", str(store), "--mesh", "plane", "--size", "64x48", *args])


def _png(path) -> np.ndarray:
    return np.asarray(Image.open(path).convert("RGB"), dtype=np.float64)


def test_png_lit_from_above_and_black_from_below(store, tmp_path):
    lit, behind = tmp_path / "lit.png", tmp_path / "behind.png"
    result = _view(store, "--light", "dir:30,0", "--camera", "orbit:0,0,100", "--out", str(lit))
    assert result.exit_code == 0, result.output
    assert "wrote" in result.output
    image = _png(lit)
    assert image.shape == (48, 64, 3)
    # Looking straight down at a plane that fills the view: every pixel shows the sample.
    assert image.min() > 0
    # A light below the plane's horizon adds nothing.
    result = _view(store, "--light", "dir:120,0", "--camera", "orbit:0,0,100", "--out", str(behind))
    assert result.exit_code == 0, result.output
    assert _png(behind).max() == 0


def test_exposure_brightens_and_exr_stays_linear(store, tmp_path):
    args = ("--light", "dir:30,0", "--camera", "orbit:0,0,100")
    assert _view(store, *args, "--exposure", "0", "--out", str(tmp_path / "a.png")).exit_code == 0
    assert _view(store, *args, "--exposure", "1", "--out", str(tmp_path / "b.png")).exit_code == 0
    assert _png(tmp_path / "b.png").mean() > 1.2 * _png(tmp_path / "a.png").mean()
    result = _view(store, *args, "--exposure", "3", "--out", str(tmp_path / "a.exr"))
    assert result.exit_code == 0, result.output
    with OpenEXR.File(str(tmp_path / "a.exr")) as exr:
        linear = exr.channels()["RGB"].pixels
    assert linear.dtype == np.float32
    assert np.isfinite(linear).all()
    # The EXR ignores the exposure: encoding it at 0 EV gives back the first PNG.
    encoded = np.where(
        linear <= 0.0031308, 12.92 * linear, 1.055 * np.clip(linear, 0, 1) ** (1 / 2.4) - 0.055
    )
    assert np.abs(np.round(np.clip(encoded, 0, 1) * 255) - _png(tmp_path / "a.png")).max() <= 1


def test_turntable_writes_a_gif_whose_frames_turn(store, tmp_path):
    out = tmp_path / "turn.gif"
    result = _view(
        store,
        "--camera",
        "orbit:50,0",
        "--light",
        "point:0,-60,60:1.5",
        "--turntable",
        "3",
        "--out",
        str(out),
    )
    assert result.exit_code == 0, result.output
    assert f"rendering {out}" in result.stderr  # the frames take a while: it says so
    with Image.open(out) as gif:
        assert gif.n_frames == 3
        frames = []
        for index in range(3):
            gif.seek(index)
            frames.append(np.asarray(gif.convert("RGB"), dtype=np.float64))
    assert frames[0].shape == (48, 64, 3)
    assert np.abs(frames[0] - frames[1]).mean() > 1.0


@pytest.mark.parametrize(
    ("args", "option", "says"),
    [
        (["--light", "sun:45,0", "--out", "x.png"], "--light", "dir:THETA,PHI"),
        (["--light", "dir:45", "--out", "x.png"], "--light", "not 2 numbers"),
        (["--light", "point:0,0,a", "--out", "x.png"], "--light", "point:X,Y,Z"),
        (["--light", "dir:45,0:-1", "--out", "x.png"], "--light", "≥ 0"),
        (["--light", "dir:40,-130:1e308", "--out", "x.png"], "--light", "1e+20"),
        (["--exposure", "1e308", "--out", "x.png"], "--exposure", "-64…64"),
        (["--exposure", "nan", "--out", "x.png"], "--exposure", "-64…64"),
        (["--camera", "orbit:200,0", "--out", "x.png"], "--camera", "0…180"),
        (["--camera", "top", "--out", "x.png"], "--camera", "orbit:THETA,PHI"),
        (["--size", "64", "--out", "x.png"], "--size", "WxH"),
        (["--out", "x.jpg"], "--out", ".png"),
        (["--turntable", "4", "--out", "x.png"], "--out", "GIF"),
        ([], "--out", "nothing to do"),
    ],
)
def test_bad_options_exit_2_naming_the_option(store, args, option, says):
    result = _view(store, *args)
    assert result.exit_code == 2, result.output
    assert option in result.output
    assert says in result.output
    assert "Traceback" not in result.output


def test_bad_material_and_meshes_exit_2_naming_the_file(store, tmp_path):
    result = _view(tmp_path / "none.zarr", "--out", str(tmp_path / "x.png"))
    assert result.exit_code == 2
    assert "none.zarr" in result.output
    stl = tmp_path / "box.stl"
    trimesh.creation.box(extents=(10, 10, 10)).export(stl)
    result = runner.invoke(
        app, ["view", str(store), "--mesh", str(stl), "--out", str(tmp_path / "x.png")]
    )
    assert result.exit_code == 2
    assert "box.stl" in result.output
    assert "no texture coordinates" in result.output
    result = runner.invoke(
        app, ["view", str(store), "--mesh", "cushion", "--out", str(tmp_path / "x.png")]
    )
    assert result.exit_code == 2
    assert "cushion" in result.output


def test_window_without_a_display_exits_1(store, monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    result = runner.invoke(app, ["view", str(store), "--window"])
    assert result.exit_code == 1
    assert "needs an X11 or Wayland display" in result.output


_WINDOW_SCRIPT = """
import json
import numpy as np
import pyglet
pyglet.options["headless"] = True  # an EGL window: no display server needed
from render.window import open_window

calls = []

def act(dt):
    window = next(iter(pyglet.app.windows))
    if len(calls) == 1:  # the first frame is up: drag, then shift-drag
        window.dispatch_event("on_mouse_drag", 5, 5, 20, 5, 1, 0)
        window.dispatch_event("on_mouse_drag", 5, 5, 10, 0, 1, pyglet.window.key.MOD_SHIFT)
    elif len(calls) > 1:
        window.close()

def draw(turn, tilt, light):
    calls.append([turn, tilt, light])
    pyglet.clock.schedule_once(act, 0.0)
    return np.full((30, 40, 3), 0.5, np.float32)

open_window(draw, size=(40, 30))
print(json.dumps(calls))
"""


def test_window_orbits_the_camera_and_turns_the_lights(tmp_path):
    """The viewer in a headless pyglet window: a drag re-renders from a turned and raised
    camera, a shift-drag with the lights turned."""
    env = {**os.environ, "DISPLAY": ":headless", "PYTHONPATH": str(Path(__file__).parents[2])}
    result = subprocess.run(
        [sys.executable, "-c", _WINDOW_SCRIPT], env=env, capture_output=True, text=True,
        timeout=60, cwd=tmp_path, check=False,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    calls = json.loads(result.stdout.strip().splitlines()[-1])
    # The drag (20, 5) px turned and raised the camera by 0.4°/px; the shift-drag (10, 0) px
    # turned only the lights; both land in the next redraw.
    assert calls == [[0.0, 0.0, 0.0], [-8.0, 2.0, 4.0]]


@pytest.mark.parametrize("mesh", ["sphere", "torus", "cloth"])
@pytest.mark.parametrize("direction", ["orbit:60,-90", "orbit:10,30", "orbit:0,0", "orbit:120,200"])
def test_orbit_camera_frames_the_whole_mesh(mesh, direction):
    """Every vertex lands in the image, and the outline fills it on its tighter side."""
    built = mesh_by_name(mesh)
    camera = parse_camera(direction).camera(built, (160, 90), 30.0)
    near, far = camera.depth_range(mesh_centre(built), 1e4)
    clip = np.c_[built.positions, np.ones(len(built.positions))] @ (
        camera.projection_matrix(near, far) @ camera.view_matrix()
    ).T.astype(np.float64)
    ndc = clip[:, :2] / clip[:, 3:]
    assert np.abs(ndc).max() <= 1.0
    # Centred: the outline reaches equally far to either side.
    assert_allclose(ndc.max(axis=0), -ndc.min(axis=0), atol=1e-3)
    assert np.abs(ndc).max() == pytest.approx(1 / 1.1, abs=0.01)


def test_point_light_power_is_the_irradiance_at_the_centre():
    centre = np.array([10.0, 0.0, 0.0])
    light = parse_light("point:10,0,200:2.5:1,0.5,0").light(centre)
    assert light.intensity / 200.0**2 == pytest.approx(2.5)
    assert light.colour == (1.0, 0.5, 0.0)
    turned = parse_light("point:110,0,0").light(centre, 90.0)
    assert_allclose(turned.position, (10.0, 100.0, 0.0), atol=1e-9)


def test_an_out_under_a_file_or_a_folder_exits_2_before_drawing(store, tmp_path):
    (tmp_path / "afile").write_text("")
    result = _view(store, "--out", str(tmp_path / "afile" / "x.png"))
    assert result.exit_code == 2, result.output
    assert f"{tmp_path / 'afile'} is a file, not a folder" in " ".join(result.output.split())
    (tmp_path / "x.png").mkdir()
    result = _view(store, "--out", str(tmp_path / "x.png"))
    assert result.exit_code == 2 and "is a folder" in result.output


def test_an_hdr_whose_header_claims_too_many_pixels_exits_2_naming_it(store, tmp_path):
    hdr = tmp_path / "big.hdr"
    hdr.write_bytes(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 100000 +X 200000\n" + bytes(64))
    result = _view(store, "--env", str(hdr), "--out", str(tmp_path / "x.png"))
    assert result.exit_code == 2, result.output
    said = " ".join(result.output.split())
    assert "big.hdr" in said and "200000×100000" in said and "OpenCV" not in said


def test_a_size_the_gl_context_cannot_draw_exits_2_naming_it(store, tmp_path):
    out = tmp_path / "x.png"
    result = runner.invoke(app, ["view", str(store), "--mesh", "plane", "--size", "16384x16384",
                                 "--out", str(out)])  # fmt: skip
    if result.exit_code == 0:
        pytest.skip("this OpenGL context draws 16384×16384")
    assert result.exit_code == 2, result.output
    said = " ".join(result.output.split())
    assert "image size 16384×16384: this OpenGL context" in said and not out.exists()


def test_a_gltf_in_metres_renders_as_the_same_plane_in_mm(store, tmp_path):
    """glTF is metres, +Y up: the built-in 100 mm plane written so renders as that plane
    (read as mm it was 0.1 mm wide, one featureless texel of the sample)."""
    flat = mesh_by_name("plane")
    x, y, z = flat.positions.T
    visual = trimesh.visual.TextureVisuals(uv=flat.uvs / 100.0)
    gltf = trimesh.Trimesh(np.stack([x, z, -y], 1) / 1000.0, flat.faces, visual=visual)
    gltf.export(tmp_path / "plane.glb")
    images = []
    for mesh in ("plane", str(tmp_path / "plane.glb")):
        out = tmp_path / f"{len(images)}.png"
        args = ["view", str(store), "--mesh", mesh, "--size", "64x48", "--tile-mm", "20"]
        result = runner.invoke(
            app, [*args, "--light", "dir:30,0", "--exposure", "0", "--out", str(out)]
        )
        assert result.exit_code == 0, result.output
        images.append(_png(out))
    assert images[0].std() > 5  # the sample's texture shows
    assert_allclose(images[1], images[0], atol=3)


def test_the_readme_caption_command_draws_the_demos_picture(store, tmp_path):
    """The command under the README's cloth picture draws what `make demo` wrote there
    (examples/demo.py's own rendering), here for a small material."""
    readme = (Path(__file__).parents[2] / "README.md").read_text()
    (command,) = re.findall(r"`(rig view out/demo/demo\.zarr [^`]*)`", readme)
    args = shlex.split(command)[1:]
    args[1], args[args.index("--out") + 1] = str(store), str(tmp_path / "caption.png")
    result = runner.invoke(app, args)
    assert result.exit_code == 0, result.output
    spec = importlib.util.spec_from_file_location(
        "demo", Path(__file__).parents[2] / "examples" / "demo.py"
    )
    demo = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(demo)
    drawn = demo._render_cloth(store, tmp_path)
    assert_allclose(_png(tmp_path / "caption.png"), _png(drawn), atol=1)
