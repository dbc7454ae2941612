"""A .glb of the fitted PBR material passes the Khronos glTF validator, and its textures
hold the maps (``make tools`` installs the validator under Node)."""

import io
import json
import shutil
import struct
import subprocess
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from rig.interchange import GLTF_EXTENSIONS, pbr_textures, srgb_decode, write_pbr_glb
from tests.rig.material.conftest import pbr_maps

ROOT = Path(__file__).resolve().parents[3]
VALIDATOR = ROOT / ".tools" / "node_modules" / "gltf-validator"
SCRIPT = Path(__file__).with_name("validate_gltf.cjs")


def _chunks(path: Path):
    data = path.read_bytes()
    magic, version, total = struct.unpack_from("<4sII", data)
    assert (magic, version, total) == (b"glTF", 2, len(data))
    length, kind = struct.unpack_from("<I4s", data, 12)
    document = json.loads(data[20 : 20 + length])
    blob_at = 20 + length
    blob_length, blob_kind = struct.unpack_from("<I4s", data, blob_at)
    assert (kind, blob_kind) == (b"JSON", b"BIN\0")
    return document, data[blob_at + 8 : blob_at + 8 + blob_length]


def _image(document, blob, name):
    image = next(i for i in document["images"] if i["name"] == name)
    view = document["bufferViews"][image["bufferView"]]
    start = view["byteOffset"]
    return np.asarray(Image.open(io.BytesIO(blob[start : start + view["byteLength"]])))


def test_the_glb_holds_the_maps_and_the_extensions(tmp_path):
    maps = pbr_maps(n=8)
    path = write_pbr_glb(tmp_path / "s.glb", pbr_textures(maps), sample_mm=40.0,
                         manifest={"fit": {"psnr_db": 31.5}})  # fmt: skip
    document, blob = _chunks(path)
    assert sorted(document["extensionsUsed"]) == sorted(GLTF_EXTENSIONS)
    assert document["asset"]["extras"]["btfrig"]["fit"]["psnr_db"] == 31.5
    base = srgb_decode(_image(document, blob, "base_colour") / 255.0)
    np.testing.assert_allclose(base, maps.base_colour, atol=0.01)
    roughness = _image(document, blob, "metallic_roughness")[..., 1] / 255.0
    np.testing.assert_allclose(roughness, maps.roughness, atol=0.5 / 255 + 1e-6)
    anisotropy = _image(document, blob, "anisotropy") / 255.0 * 2 - 1
    phi = np.deg2rad(maps.anisotropy_deg)
    np.testing.assert_allclose(anisotropy[..., 0], np.cos(phi), atol=0.01)
    position = document["accessors"][
        document["meshes"][0]["primitives"][0]["attributes"]["POSITION"]
    ]
    assert position["max"][0] == pytest.approx(0.02)


def test_the_khronos_validator_finds_no_error(tmp_path):
    node = shutil.which("node")
    if node is None or not VALIDATOR.is_dir():
        pytest.skip(
            "the glTF validator is not installed: `make tools` (needs Debian's nodejs, npm)"
        )
    path = write_pbr_glb(tmp_path / "s.glb", pbr_textures(pbr_maps(n=16)), sample_mm=40.0)
    run = subprocess.run([node, str(SCRIPT), str(VALIDATOR), str(path)],
                         capture_output=True, text=True, timeout=120, check=False)  # fmt: skip
    assert run.returncode == 0, run.stderr
    report = json.loads(run.stdout)
    issues = report["issues"]
    assert issues["numErrors"] == 0, issues["messages"]
    assert issues["numWarnings"] == 0, issues["messages"]
    used = report["info"]["extensionsUsed"]
    assert sorted(used) == sorted(GLTF_EXTENSIONS)
