"""`rig view --env`: a material lit by an environment map; bad environments exit 2."""

import cv2
import numpy as np
import OpenEXR
import pytest
from PIL import Image
from typer.testing import CliRunner

from orchestrator.cli import app
from render.environment import synthetic_environment

runner = CliRunner()


def _view(store, *args, mesh="sphere"):
    return runner.invoke(
        app, ["view", str(store), "--mesh", mesh, "--size", "48x48", "--vis-res", "4", *args]
    )


def _png(path) -> np.ndarray:
    return np.asarray(Image.open(path).convert("RGB"), dtype=np.float64)


def test_environment_file_lights_the_sphere_and_turns(store, tmp_path):
    env = tmp_path / "window.hdr"
    radiance = synthetic_environment("window", height=16).radiance
    assert cv2.imwrite(str(env), np.ascontiguousarray(radiance[..., ::-1]))
    images = {}
    for turn in (0, 180):
        out = tmp_path / f"turn{turn}.png"
        result = _view(
            store, "--env", str(env), "--env-rotate", str(turn), "--exposure", "0",
            "--camera", "orbit:70,90", "--out", str(out),
        )  # fmt: skip
        assert result.exit_code == 0, result.output
        assert "window.hdr" in result.output
        images[turn] = _png(out)
    # The window is at φ 60–120°, on the camera's side: turned away, the front goes dark.
    assert images[0].mean() > 2 * images[180].mean()


def test_pca_method_draws_a_turntable(store, tmp_path):
    out = tmp_path / "turn.gif"
    result = _view(
        store, "--env", "studio", "--env-method", "pca", "--turntable", "3", "--out", str(out),
        mesh="plane",
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    with Image.open(out) as frames:
        assert frames.n_frames == 3


def test_bad_environment_options_exit_2_naming_them(store, tmp_path):
    out = str(tmp_path / "x.png")
    (tmp_path / "square.exr").write_bytes(b"junk")
    for args, named in (
        (["--env", "beach"], "--env"),
        (["--env", str(tmp_path / "square.exr")], "square.exr"),
        (["--env", "sky", "--env-method", "median"], "--env-method"),
        (["--env", "sky", "--vis-res", "5"], "--vis-res"),
    ):
        result = _view(store, *args, "--out", out)
        assert result.exit_code == 2, (args, result.output)
        assert named in result.output, (args, result.output)
        assert "Traceback" not in result.output


def test_pem_method_draws_partial_environment_maps(store, tmp_path):
    out = tmp_path / "pem.png"
    result = _view(store, "--env", "sky", "--env-method", "pem", "--median-cut", "16",
                   "--out", str(out))  # fmt: skip
    assert result.exit_code == 0, result.output
    assert _png(out).max() > 0
    result = _view(store, "--env", "sky", "--env-method", "pem", "--median-cut", "12",
                   "--out", str(out))  # fmt: skip
    assert result.exit_code == 2 and "--median-cut" in result.output


def _exr(path) -> np.ndarray:
    with OpenEXR.File(str(path)) as exr:
        return np.asarray(exr.channels()["RGB"].pixels, np.float64)


@pytest.mark.parametrize("method", ["visibility", "pem"])
def test_lights_add_to_the_environment(store, tmp_path, method):
    """Light adds up: environment + a lamp is the environment's image plus the lamp's."""
    common = ["--camera", "orbit:0,0,100", "--env-method", method]
    images = {}
    for name, args in (
        ("both", ["--env", "window", "--light", "dir:30,0:0.5"]),
        ("env", ["--env", "window"]),
        ("lamp", ["--light", "dir:30,0:0.5"]),
    ):
        out = tmp_path / f"{name}.exr"
        result = _view(store, *common, *args, "--out", str(out), mesh="plane")
        assert result.exit_code == 0, result.output
        images[name] = _exr(out)
    assert images["env"].max() > 0 and images["lamp"].max() > 0
    np.testing.assert_allclose(
        images["both"], images["env"] + images["lamp"], rtol=1e-5, atol=1e-6 * images["both"].max()
    )


def test_vis_res_defaults_to_the_renderers_default():
    """`rig view --env` without --vis-res gets the renderer's default hemicube (the one the
    docs' sky figure and its accuracy table were made with), not the faster preview."""
    import typer

    from render.environment.visibility import DEFAULT_RESOLUTION

    view = typer.main.get_command(app).commands["view"]
    vis_res = next(p for p in view.params if p.name == "vis_res")
    assert vis_res.default == DEFAULT_RESOLUTION == 16
