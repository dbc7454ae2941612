"""`rig export maps` and `rig export gltf`: a bumps surface's PS maps come back from the
files — normals within 16-bit (maps) or 8-bit (glb) quantisation, height to mm."""

import json

import numpy as np
import pytest
import trimesh
from typer.testing import CliRunner

from orchestrator.cli import app
from render.meshes import load_mesh
from rig.geometry import texel_centers_mm
from rig.interchange import decode_normal_map, read_image, srgb_decode
from rig.material import PsView
from tests.rig.material.conftest import SAMPLE_MM, make_archive

runner = CliRunner()
N = 32


def bumps_view() -> PsView:
    """PS maps of h = 0.8 mm · exp(−r²/(2·8²)) around (10, 15) mm plus a slope along +y."""
    xy = texel_centers_mm(SAMPLE_MM, N)
    x, y = xy[..., 0] - 10.0, xy[..., 1] - 15.0
    bump = 0.8 * np.exp(-(x**2 + y**2) / (2 * 8.0**2))
    height = bump + 0.02 * xy[..., 1]
    dh_dx = -x / 8.0**2 * bump
    dh_dy = -y / 8.0**2 * bump + 0.02
    normals = np.stack([-dh_dx, -dh_dy, np.ones_like(x)], axis=-1)
    normals /= np.linalg.norm(normals, axis=-1, keepdims=True)
    valid = np.ones((N, N), bool)
    valid[0, :4] = False
    albedo = np.stack([0.2 + 0.6 * (xy[..., 0] > 0), np.full((N, N), 0.5), 0.3 + 0 * x], -1)
    return PsView(
        "cam0_tt000.0", normals.astype(np.float32), albedo.astype(np.float32), valid,
        np.where(valid, 0, 3).astype(np.uint8), height.astype(np.float32), view_deg=(0.0, 0.0),
    )  # fmt: skip


@pytest.fixture(scope="module")
def archive(tmp_path_factory):
    return make_archive(tmp_path_factory.mktemp("maps") / "s.zarr", ps=[bumps_view()])


def test_maps_decode_to_the_ps_normals_albedo_and_height(archive, tmp_path):
    result = runner.invoke(app, ["export", "maps", str(archive), "--out", str(tmp_path / "m")])
    assert result.exit_code == 0, result.output
    view = bumps_view()
    manifest = json.loads((tmp_path / "m" / "manifest.json").read_text())
    normal = read_image(tmp_path / "m" / "normal.png")
    assert normal.dtype == np.uint16
    decoded = decode_normal_map(normal)
    np.testing.assert_allclose(decoded[view.valid], view.normals[view.valid], atol=5e-5)
    np.testing.assert_allclose(decoded[~view.valid], [[0, 0, 1]] * 4, atol=5e-5)
    # OpenGL convention: the slope rises towards +y, the top of the image → green below ½
    assert normal[N - 1, 0, 1] < 32767 and manifest["normal"]["convention"] == "OpenGL (+Y up)"
    height = manifest["height"]
    counts = read_image(tmp_path / "m" / "height.png")[..., 0]
    in_mm = height["height_min_mm"] + counts * height["mm_per_count"]
    np.testing.assert_allclose(in_mm, view.height_mm, atol=height["mm_per_count"] / 2 + 1e-7)
    assert height["mm_per_count"] == pytest.approx(np.ptp(view.height_mm) / 65535, rel=1e-6)
    exr = read_image(tmp_path / "m" / "height.exr")[..., 0]
    np.testing.assert_array_equal(exr, view.height_mm)
    albedo = srgb_decode(read_image(tmp_path / "m" / "albedo.png") / 255.0)
    np.testing.assert_allclose(albedo[view.valid], view.albedo[view.valid], atol=0.004)
    assert manifest["sample_mm"] == SAMPLE_MM and manifest["view"] == "cam0_tt000.0"


def test_the_glb_opens_in_trimesh_with_its_maps(archive, tmp_path):
    out = tmp_path / "sample.glb"
    result = runner.invoke(app, ["export", "gltf", str(archive), "--out", str(out)])
    assert result.exit_code == 0, result.output
    scene = trimesh.load(out)
    (mesh,) = scene.geometry.values()
    material = mesh.visual.material
    view = bumps_view()
    normal = np.asarray(material.normalTexture.convert("RGB"))
    decoded = decode_normal_map(normal)
    np.testing.assert_allclose(decoded[view.valid], view.normals[view.valid], atol=0.01)
    albedo = srgb_decode(np.asarray(material.baseColorTexture.convert("RGB")) / 255.0)
    np.testing.assert_allclose(albedo[view.valid], view.albedo[view.valid], atol=0.004)
    # the plane is the sample (metres, +Y up); texel row 0, column 0 (−x, +y) sits at
    # glTF (−X, −Z), which trimesh gives the UV of the image's top-left corner (0, 1)
    np.testing.assert_allclose(np.ptp(mesh.vertices, axis=0), [0.06, 0, 0.06])
    corner = np.argmin(mesh.vertices[:, 0] + mesh.vertices[:, 2])
    np.testing.assert_allclose(mesh.visual.uv[corner], [0, 1])
    np.testing.assert_allclose(mesh.face_normals, [[0, 1, 0]] * 2, atol=1e-12)


def test_overwrite_replaces_only_a_glb_btfrig_wrote(archive, tmp_path):
    ours, foreign = tmp_path / "ours.glb", tmp_path / "foreign.glb"
    assert runner.invoke(app, ["export", "gltf", str(archive), "--out", str(ours)]).exit_code == 0
    trimesh.Scene(trimesh.creation.box()).export(foreign)  # another tool's generator
    data = foreign.read_bytes()
    refused = runner.invoke(
        app, ["export", "gltf", str(archive), "--out", str(foreign), "--overwrite"]
    )
    assert refused.exit_code == 2
    assert "is not an earlier btfrig export" in " ".join(refused.output.split())
    assert foreign.read_bytes() == data
    again = runner.invoke(app, ["export", "gltf", str(archive), "--out", str(ours), "--overwrite"])
    assert again.exit_code == 0, again.output


def test_an_archive_without_maps_fails_naming_it(tmp_path):
    bare = make_archive(tmp_path / "b.zarr")
    result = runner.invoke(app, ["export", "maps", str(bare), "--out", str(tmp_path / "m")])
    assert result.exit_code == 1
    assert "b.zarr/material: holds none of btf, ps, mdf, pbr" in " ".join(result.output.split())
    assert not (tmp_path / "m").exists()
    wrong = runner.invoke(app, ["export", "gltf", str(bare), "--out", str(tmp_path / "x.gltf")])
    assert wrong.exit_code == 2 and "suffix .glb" in " ".join(wrong.output.split())


def test_a_mesh_with_uvs_carries_the_maps(archive, tmp_path):
    plane = tmp_path / "plane.glb"
    assert runner.invoke(app, ["export", "gltf", str(archive), "--out", str(plane)]).exit_code == 0
    out = tmp_path / "on_mesh.glb"
    args = ["export", "gltf", str(archive), "--out", str(out), "--mesh", str(plane)]
    assert runner.invoke(app, args).exit_code == 0
    (mesh,) = trimesh.load(out).geometry.values()
    assert mesh.visual.material.normalTexture.size == (N, N)
    (tmp_path / "flat.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    args[-1] = str(tmp_path / "flat.obj")
    refused = runner.invoke(app, [*args[:4], str(tmp_path / "x.glb"), *args[5:]])
    assert refused.exit_code == 2 and "has no UV per vertex" in " ".join(refused.output.split())


def test_the_glb_comes_back_to_the_renderer_at_the_samples_size(archive, tmp_path):
    """export → view: glTF's metres and +Y up are read as mm and +Z up, so the plane is
    the sample at its size (read as mm it was 1000 times too small: one texel wide)."""
    out = tmp_path / "sample.glb"
    assert runner.invoke(app, ["export", "gltf", str(archive), "--out", str(out)]).exit_code == 0
    mesh = load_mesh(out)
    np.testing.assert_allclose(np.ptp(mesh.positions, axis=0), [SAMPLE_MM, SAMPLE_MM, 0])
    np.testing.assert_allclose(np.ptp(mesh.uvs, axis=0), [SAMPLE_MM, SAMPLE_MM], rtol=1e-6)
    np.testing.assert_allclose(mesh.normals, [[0, 0, 1]] * len(mesh.normals), atol=1e-6)
    # texel row 0, column 0 (−x, +y) keeps its corner of the UV square
    corner = np.argmin(mesh.positions[:, 0] - mesh.positions[:, 1])
    np.testing.assert_allclose(mesh.uvs[corner], [0, SAMPLE_MM], atol=1e-9)


def test_a_mesh_in_mm_is_written_in_metres(archive, tmp_path):
    (tmp_path / "quad.obj").write_text(
        "v 0 0 0\nv 60 0 0\nv 60 60 0\nv 0 60 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
        "f 1/1 2/2 3/3\nf 1/1 3/3 4/4\n"
    )
    out = tmp_path / "quad.glb"
    args = ["export", "gltf", str(archive), "--out", str(out), "--mesh", str(tmp_path / "quad.obj")]
    assert runner.invoke(app, args).exit_code == 0
    (written,) = trimesh.load(out).geometry.values()
    np.testing.assert_allclose(np.ptp(written.vertices, axis=0), [0.06, 0, 0.06])  # +Y up
    np.testing.assert_allclose(np.ptp(load_mesh(out).positions, axis=0), [60, 60, 0], atol=1e-9)
