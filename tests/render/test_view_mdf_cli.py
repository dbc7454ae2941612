"""`rig view --mdf/--no-mdf --peel N`: silhouettes from a store's MDF, exit codes."""

import shutil

import numpy as np
import pytest
import zarr
from PIL import Image
from typer.testing import CliRunner

from orchestrator.cli import app
from rig.material import write_mdf
from tests.render.conftest import synthetic_mdf

runner = CliRunner()
# Lit from the camera, so every pixel it sees is lit and only the background is black.
TORUS = ("--mesh", "torus", "--size", "96x64", "--camera", "orbit:80,-90", "--light", "dir:80,-90")


@pytest.fixture(scope="module")
def mdf_store(store, tmp_path_factory):
    """The PCA store with an MDF of depths up to 2 mm added."""
    path = tmp_path_factory.mktemp("mdf") / "m.zarr"
    shutil.copytree(store, path)
    write_mdf(zarr.open_group(path, mode="a").create_group("mdf"), synthetic_mdf(n=16))
    return path


def _covered(path) -> int:
    return int((np.asarray(Image.open(path).convert("L")) > 0).sum())


def test_mdf_trims_the_outline_and_no_mdf_keeps_it(mdf_store, tmp_path):
    # --tile-mm 100: the 20 mm sample's depths × 5, a few pixels at this size.
    common = (*TORUS, "--tile-mm", "100", "--exposure", "4")
    images = {}
    for name, flags in (("auto", ()), ("on", ("--mdf", "--peel", "1")), ("off", ("--no-mdf",))):
        out = tmp_path / f"{name}.png"
        result = runner.invoke(app, ["view", str(mdf_store), *common, *flags, "--out", str(out)])
        assert result.exit_code == 0, result.output
        images[name] = _covered(out)
    assert images["auto"] < images["off"] - 20
    assert images["on"] <= images["auto"]


def test_mdf_on_a_material_without_one_exits_2_naming_it(store, tmp_path):
    result = runner.invoke(
        app, ["view", str(store), *TORUS, "--mdf", "--out", str(tmp_path / "x.png")]
    )
    assert result.exit_code == 2, result.output
    assert "holds no mdf" in result.output
    assert str(store.name) in result.output
    assert "Traceback" not in result.output


@pytest.mark.parametrize(
    ("args", "option", "says"),
    [
        (["--peel", "0"], "--peel", "greater than or equal to 1"),
        (["--peel", "9"], "--peel", "less than or equal to 8"),
        (["--mdf", "--env", "sky", "--env-method", "pca"], "--mdf", "--env-method pem"),
    ],
)
def test_bad_silhouette_options_exit_2_naming_them(mdf_store, tmp_path, args, option, says):
    result = runner.invoke(
        app, ["view", str(mdf_store), *TORUS, *args, "--out", str(tmp_path / "x.png")]
    )
    assert result.exit_code == 2, result.output
    assert option in result.output
    assert says in result.output


def test_partial_environment_maps_draw_the_silhouettes_too(mdf_store, tmp_path):
    common = (*TORUS, "--tile-mm", "100", "--exposure", "4", "--env", "sky", "--env-method", "pem")
    images = {}
    for flag in ("--mdf", "--no-mdf"):
        out = tmp_path / f"{flag}.png"
        result = runner.invoke(app, ["view", str(mdf_store), *common, flag, "--out", str(out)])
        assert result.exit_code == 0, result.output
        images[flag] = np.asarray(Image.open(out).convert("RGB"), np.int16)
    drawn = {flag: image.sum(axis=-1) > 0 for flag, image in images.items()}
    assert drawn["--mdf"].sum() < drawn["--no-mdf"].sum() - 20
    assert not np.any(drawn["--mdf"] & ~drawn["--no-mdf"])
