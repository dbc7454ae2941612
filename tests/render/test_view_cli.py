"""`rig view`: images, EXR, turntable GIF from a small material store; exit codes for bad input."""

import numpy as np
import OpenEXR
import pytest
import trimesh
import zarr
from PIL import Image
from typer.testing import CliRunner

from orchestrator.cli import app
from rig.material import write_btf
from tests.render.conftest import SAMPLE_MM

runner = CliRunner()


@pytest.fixture(scope="module")
def store(tmp_path_factory, pca_model):
    """A standalone material store holding a 16 × 16 per-view PCA BTF."""
    path = tmp_path_factory.mktemp("view") / "m.zarr"
    root = zarr.open_group(path, mode="w", zarr_format=3)
    root.attrs.update(
        format="btfrig.material", version=1, sample_mm=SAMPLE_MM, size=16, provenance={}
    )
    write_btf(root.create_group("btf"), pca_model, units="relative radiance")
    return path


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
    assert _view(store, *args, "--out", str(tmp_path / "a.png")).exit_code == 0
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
