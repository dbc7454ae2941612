"""`rig process --stages pbr`, `rig export gltf` and `rig export materialx` on a material
with a BTF: the fit lands in material/pbr, the exports carry it and its error."""

import json
import shutil
import subprocess

import numpy as np
import pytest
from numpy.testing import assert_allclose
from typer.testing import CliRunner

from orchestrator.cli import app
from rig.interchange import GLTF_EXTENSIONS
from rig.material import read_material
from tests.rig.interchange.test_gltf_pbr import SCRIPT, VALIDATOR, _chunks
from tests.rig.material.conftest import make_archive, pbr_maps, pca_model, ps_view

# Simulated sessions, rendered targets or fits of seconds each: make test only, not make quick.
pytestmark = pytest.mark.slow

runner = CliRunner()
NO_VALIDATOR = "the glTF validator is not installed: `make tools` (needs Debian's nodejs, npm)"


def _words(result) -> str:
    return " ".join(result.output.split())


@pytest.fixture
def fitted(tmp_path):
    """An archive with a BTF and PS maps, processed by `rig process --stages pbr`."""
    path = make_archive(
        tmp_path / "s.zarr", btf=pca_model(), ps=[ps_view("cam0_tt000.0", (0.0, 0.0))]
    )
    result = runner.invoke(app, ["process", str(path), "--stages", "pbr"])
    assert result.exit_code == 0, result.output
    return path


def test_the_stage_writes_finite_maps_and_their_error(fitted):
    material = read_material(fitted)
    pbr = material.pbr
    assert pbr.size == material.btf.size
    assert np.all(np.isfinite(pbr.error_rmse)) and np.all(pbr.error_rmse >= 0)
    assert pbr.attrs["height_source"] == "ps"
    assert np.isfinite(pbr.attrs["psnr_db"])


def test_gltf_carries_the_fit_and_passes_the_validator(fitted, tmp_path):
    out = tmp_path / "s.glb"
    result = runner.invoke(app, ["export", "gltf", str(fitted), "--out", str(out)])
    assert result.exit_code == 0, result.output
    assert "dB against the BTF" in _words(result)
    document, _ = _chunks(out)
    assert sorted(document["extensionsUsed"]) == sorted(GLTF_EXTENSIONS)
    fit = document["asset"]["extras"]["btfrig"]["fit"]
    assert fit["psnr_db"] == pytest.approx(read_material(fitted).pbr.attrs["psnr_db"])
    node = shutil.which("node")
    if node is None or not VALIDATOR.is_dir():
        pytest.skip(
            "the glTF validator is not installed: `make tools` (needs Debian's nodejs, npm)"
        )
    run = subprocess.run([node, str(SCRIPT), str(VALIDATOR), str(out)],
                         capture_output=True, text=True, timeout=120, check=False)  # fmt: skip
    assert json.loads(run.stdout)["issues"]["numErrors"] == 0


def test_materialx_validates_with_the_standard_library(fitted, tmp_path):
    mx = pytest.importorskip(
        "MaterialX", reason="materialx is not installed: pip install '.[export]'"
    )
    out = tmp_path / "mtlx"
    result = runner.invoke(app, ["export", "materialx", str(fitted), "--out", str(out)])
    assert result.exit_code == 0, result.output
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["fit"]["psnr_db"] == pytest.approx(read_material(fitted).pbr.attrs["psnr_db"])
    doc = mx.createDocument()
    mx.readFromXmlFile(doc, str(out / manifest["document"]))
    library = mx.createDocument()
    mx.loadLibraries(mx.getDefaultDataLibraryFolders(), mx.getDefaultDataSearchPath(), library)
    doc.importLibrary(library)
    valid, message = doc.validate()
    assert valid, message
    images = doc.getNodes("image")
    assert len(images) == 8
    for node in images:
        assert (out / node.getInputValue("file")).is_file()


def test_exports_without_a_fit_say_how_to_make_one(tmp_path):
    path = make_archive(tmp_path / "p.zarr", ps=[ps_view("cam0_tt000.0", (0.0, 0.0))])
    result = runner.invoke(app, ["export", "materialx", str(path), "--out", str(tmp_path / "m")])
    assert result.exit_code == 2
    assert "has no PBR fit; run `rig process --stages pbr` first" in _words(result)
    assert not (tmp_path / "m").exists()


def test_a_material_with_only_a_fit_reads(tmp_path):
    path = make_archive(tmp_path / "f.zarr", pbr=pbr_maps(n=4))
    assert read_material(path).size == 4


def test_gltf_on_a_mesh_file_keeps_its_uvs(fitted, tmp_path):
    obj = tmp_path / "quad.obj"
    obj.write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
                   "f 1/1 2/2 3/3\nf 1/1 3/3 4/4\n")  # fmt: skip
    out = tmp_path / "quad.glb"
    args = ["export", "gltf", str(fitted), "--out", str(out), "--mesh", str(obj)]
    result = runner.invoke(app, args)
    assert result.exit_code == 0, result.output
    document, blob = _chunks(out)
    primitive = document["meshes"][0]["primitives"][0]

    def attribute(name, width):
        accessor = document["accessors"][primitive["attributes"][name]]
        start = document["bufferViews"][accessor["bufferView"]]["byteOffset"]
        return np.frombuffer(blob, np.float32, accessor["count"] * width, start).reshape(-1, width)

    uvs, positions = attribute("TEXCOORD_0", 2), attribute("POSITION", 3)
    # the OBJ's mm with +Z up are glTF's metres with +Y up: its (x, y) is glTF's (x, −z);
    # glTF's v runs down the image: the OBJ's corner at v = 0 has glTF's v = 1
    assert_allclose(positions[:, 1], 0.0)
    pairs = {(round(1000 * p[0], 3), round(-1000 * p[2], 3)): tuple(uv.round(6))
             for p, uv in zip(positions, uvs, strict=True)}  # fmt: skip
    assert pairs == {(0, 0): (0, 1), (1, 0): (1, 1), (1, 1): (1, 0), (0, 1): (0, 0)}
    assert "TANGENT" not in primitive["attributes"]
    node = shutil.which("node")
    if node is None or not VALIDATOR.is_dir():
        pytest.skip(NO_VALIDATOR)
    run = subprocess.run([node, str(SCRIPT), str(VALIDATOR), str(out)],
                         capture_output=True, text=True, timeout=120, check=False)  # fmt: skip
    assert json.loads(run.stdout)["issues"]["numErrors"] == 0
