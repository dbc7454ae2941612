"""`rig import` and `rig export`: round trips through the UBO2003 layout, frames with a
manifest, the PS maps and a glTF; bad input exits 2 naming the file, the archive is
never modified, an existing output is replaced only with --overwrite."""

import hashlib
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from orchestrator.cli import app
from rig.archive import Archive, FrameFormat, StepRecord
from rig.interchange import NORMTEXTURE_CAMERA, read_image, srgb_decode, write_image
from tests.rig.interchange.conftest import LIGHTS, SIZE, VIEWS, normtexture, write_ubo_folder

runner = CliRunner()


def _run(*args):
    result = runner.invoke(app, [str(a) for a in args])
    assert "Traceback" not in result.output
    return result


def _said(result) -> str:
    return " ".join(result.output.split())


def _tree_digest(path) -> str:
    digest = hashlib.sha256()
    for file in sorted(p for p in path.rglob("*") if p.is_file()):
        digest.update(str(file.relative_to(path)).encode() + file.read_bytes())
    return digest.hexdigest()


def _normtextures(archive_path) -> dict:
    with Archive.open(archive_path) as archive:
        return {
            (s.views_deg[NORMTEXTURE_CAMERA], s.light_deg): archive.read_frame(
                s.index, NORMTEXTURE_CAMERA
            )
            for s in archive.step_table()
        }


@pytest.fixture
def imported(tmp_path):
    folder = write_ubo_folder(tmp_path / "ubo", skip={(VIEWS[2], LIGHTS[1])})
    result = _run("import", folder, "--out", tmp_path / "a.zarr", "--sample-mm", 40)
    assert result.exit_code == 0, result.output
    said = _said(result)
    assert "14 frames (ubo2003), 3 views × 5 lights, 32×32×3, srgb → linear, sample 40 mm" in said
    assert "gap: view (30°, 90°): 1 of 5 lights missing: (30°, 0°)" in _said(result)
    return tmp_path / "a.zarr"


def test_ubo2003_export_then_import_gives_the_same_normtextures(imported, tmp_path):
    before = _tree_digest(imported)
    result = _run("export", "ubo2003", imported, "--out", tmp_path / "out")
    assert result.exit_code == 0, result.output
    assert _tree_digest(imported) == before  # an export never modifies the archive
    manifest = json.loads((tmp_path / "out" / "manifest.json").read_text())
    assert len(manifest["gaps"]) == 1 and manifest["white"] == 1.0
    again = _run("import", tmp_path / "out", "--out", tmp_path / "b.zarr")
    assert again.exit_code == 0, again.output
    assert "sample 40 mm" in _said(again)  # from the export's manifest
    first, second = _normtextures(imported), _normtextures(tmp_path / "b.zarr")
    assert set(first) == set(second)  # the same directions, the gap included
    for pair, texture in first.items():
        np.testing.assert_array_equal(second[pair], texture)  # 8-bit codes survive exactly


def test_an_existing_output_needs_overwrite_and_must_be_an_export(imported, tmp_path):
    out = tmp_path / "out"
    assert _run("export", "ubo2003", imported, "--out", out).exit_code == 0
    refused = _run("export", "ubo2003", imported, "--out", out)
    assert refused.exit_code == 2 and "already exists; give a new path or --overwrite" in _said(
        refused
    )
    assert _run("export", "ubo2003", imported, "--out", out, "--overwrite").exit_code == 0
    (tmp_path / "mine").mkdir()
    other = _run("export", "ubo2003", imported, "--out", tmp_path / "mine", "--overwrite")
    assert other.exit_code == 2 and "is not an earlier btfrig export" in _said(other)
    inside = _run("export", "exr", imported, "--out", imported / "x")
    assert inside.exit_code == 2 and "lies in or around the archive" in _said(inside)


def test_overwrite_replaces_only_a_folder_btfrig_wrote(imported, tmp_path):
    # A web app's folder with its own manifest.json.
    web_app = tmp_path / "webapp"
    web_app.mkdir()
    (web_app / "manifest.json").write_text('{"name": "my app"}')
    (web_app / "index.js").write_text("console.log(1)")
    refused = _run("export", "ubo2003", imported, "--out", web_app, "--overwrite")
    assert refused.exit_code == 2 and "is not an earlier btfrig export" in _said(refused)
    assert sorted(p.name for p in web_app.iterdir()) == ["index.js", "manifest.json"]
    assert (web_app / "index.js").read_text() == "console.log(1)"


def test_an_imported_set_is_processed_and_viewed(tmp_path):
    folder = write_ubo_folder(tmp_path / "ubo")
    archive = tmp_path / "a.zarr"
    assert _run("import", folder, "--out", archive, "--sample-mm", 40).exit_code == 0
    processed = _run("process", archive, "--stages", "btf", "--size", SIZE, "--components", 5)
    assert processed.exit_code == 0, processed.output
    assert "btf: 3 item(s) → material/btf" in _said(processed)
    out = tmp_path / "recon"
    assert _run("export", "ubo2003", archive, "--out", out, "--from-material").exit_code == 0
    view, light = VIEWS[1], LIGHTS[3]
    image = read_image(out / "tv015_pv060" / "00003 tl030 pl240 tv015 pv060.png")
    white = json.loads((out / "manifest.json").read_text())["white"]
    assert 0.5 < white < 1.0  # the brightest 0.1 % of the frontal slot (≤ 0.9 here)
    # 5 lights, 5 components: the PCA is exact up to float16 storage and 8-bit sRGB
    linear = white * srgb_decode(image / 255.0)
    np.testing.assert_allclose(linear, normtexture(view, light), atol=0.01)
    picture = tmp_path / "v.png"
    viewed = _run("view", archive, "--mesh", "plane", "--size", "64x48", "--out", picture)
    assert viewed.exit_code == 0, viewed.output
    assert read_image(picture).std() > 0


@pytest.mark.parametrize(
    ("entry", "complaint"),
    [
        ("stray.txt", "not a UBO2003 view folder"),
        ("tv000_pv000/picture.png", "not a UBO2003 image name"),
    ],
)
def test_bad_import_input_exits_2_naming_the_file(tmp_path, entry, complaint):
    folder = write_ubo_folder(tmp_path / "ubo", views=VIEWS[:1])
    (folder / entry).write_bytes(b"x")
    result = _run("import", folder, "--out", tmp_path / "a.zarr")
    assert result.exit_code == 2
    assert complaint in _said(result) and entry.split("/")[-1] in _said(result)
    assert not (tmp_path / "a.zarr").exists()


@pytest.fixture
def session(tmp_path):
    """A captured session's archive: 8-bit and 16-bit cameras, two btf steps."""
    rng = np.random.default_rng(5)
    path = tmp_path / "s.zarr"
    cameras = {"cam0": FrameFormat(6, 8, 3, "uint8"), "cam1": FrameFormat(6, 8, 1, "uint16")}
    frames = {}
    with Archive.create(path, plan={"name": "s"}, rig_config={}, cameras=cameras,
                        fsync=False) as archive:  # fmt: skip
        for index in range(2):
            step = StepRecord(
                index, "btf", ("cam0", "cam1"), views_deg={"cam0": (0, 0), "cam1": (30, 90)},
                light_deg=(45.0, 120.0 * index), exposures_s=(0.01,), lamp=f"lamp{index}",
            )  # fmt: skip
            shot = {
                "cam0": rng.integers(0, 256, (6, 8, 3), dtype=np.uint8),
                "cam1": rng.integers(0, 65536, (6, 8, 1), dtype=np.uint16),
            }
            archive.append_step(step, {c: [image] for c, image in shot.items()})
            frames.update({(index, c): image for c, image in shot.items()})
    return path, frames


@pytest.mark.parametrize(("fmt", "suffix"), [("png16", ".png"), ("tiff", ".tif"), ("exr", ".exr")])
def test_frames_are_written_raw_with_a_manifest(session, tmp_path, fmt, suffix):
    path, frames = session
    before = _tree_digest(path)
    result = _run("export", fmt, path, "--out", tmp_path / "f")
    assert result.exit_code == 0, result.output
    assert _tree_digest(path) == before
    manifest = json.loads((tmp_path / "f" / "manifest.json").read_text())
    assert len(manifest["frames"]) == 4
    for entry in manifest["frames"]:
        scale = manifest["cameras"][entry["camera"]]["value_scale"]
        written = read_image(tmp_path / "f" / entry["file"])
        assert entry["file"].endswith(suffix)
        original = frames[(entry["step"], entry["camera"])]
        np.testing.assert_array_equal(written / scale, original)
        assert entry["lamp"] == f"lamp{entry['step']}" and entry["exposure_s"] == 0.01
        assert entry["light_deg"] == [45.0, 120.0 * entry["step"]]
    assert manifest["frames"][1]["view_deg"] == [30.0, 90.0]


def test_a_missing_archive_exits_2_naming_it(tmp_path):
    result = _run("export", "png16", tmp_path / "nowhere.zarr", "--out", tmp_path / "f")
    assert result.exit_code == 2 and "nowhere.zarr: not a session archive" in _said(result)


def test_the_white_level_of_an_export_is_undone_by_the_import(imported, tmp_path):
    out = tmp_path / "out"
    assert _run("export", "ubo2003", imported, "--out", out, "--white", 2).exit_code == 0
    assert _run("import", out, "--out", tmp_path / "b.zarr").exit_code == 0
    first, second = _normtextures(imported), _normtextures(tmp_path / "b.zarr")
    for pair, texture in first.items():
        # codes of v/2: the sRGB step near v/2 = 0.45 is 0.0045 → 0.009 after ×2
        np.testing.assert_allclose(second[pair], texture, atol=0.01)


@pytest.mark.parametrize(
    ("view", "name", "named"),
    [("tv120_pv000", "00000 tl000 pl000 tv120 pv000.png", "tv120_pv000: view = (120°"),
     ("tv000_pv000", "00009 tl999 pl000 tv000 pv000.png", "pv000.png: light = (999°")],
)  # fmt: skip
def test_a_direction_below_the_horizon_exits_2_naming_the_file(tmp_path, view, name, named):
    folder = write_ubo_folder(tmp_path / "ubo", views=VIEWS[:1])
    (folder / view).mkdir(exist_ok=True)
    write_image(folder / view / name, np.zeros((SIZE, SIZE, 3), np.uint8))
    result = _run("import", folder, "--out", tmp_path / "a.zarr")
    assert result.exit_code == 2, result.output
    assert named in _said(result) and "below the horizon" in _said(result)


_TERMINATED_IMPORT = """
import os, signal, sys
import rig.interchange._import as importer
real, calls = importer.read_image, []
def read_image(path):
    calls.append(path)
    if len(calls) == 3:  # mid-import, with frames in the archive already
        os.kill(os.getpid(), signal.SIGTERM)
    return real(path)
importer.read_image = read_image
from orchestrator.cli import main
sys.argv = ["rig", "import", sys.argv[1], "--out", sys.argv[2]]
main()
"""


def test_sigterm_during_an_import_leaves_no_archive(tmp_path):
    folder = write_ubo_folder(tmp_path / "ubo")
    out = tmp_path / "a.zarr"
    done = subprocess.run(
        [sys.executable, "-c", _TERMINATED_IMPORT, str(folder), str(out)],
        capture_output=True, text=True, timeout=120, cwd=Path(__file__).resolve().parents[2],
    )  # fmt: skip
    assert done.returncode == 130, done.stdout + done.stderr  # as after Ctrl-C
    assert "Traceback" not in done.stdout + done.stderr
    assert not out.exists()


def test_a_btf_holding_nan_is_refused_by_view_and_export_naming_the_array(tmp_path):
    import zarr

    imported = tmp_path / "a.zarr"
    assert _run("import", write_ubo_folder(tmp_path / "ubo"), "--out", imported).exit_code == 0
    processed = _run("process", imported, "--stages", "btf", "--size", SIZE, "--components", 4)
    assert processed.exit_code == 0, processed.output
    group = zarr.open_group(imported / "material" / "btf", mode="r+")
    basis = group["basis"][...]
    basis[0, 0, 5, 5, 1] = np.nan
    group["basis"][...] = basis
    picture = tmp_path / "v.png"
    viewed = _run("view", imported, "--mesh", "plane", "--size", "32x32", "--out", picture)
    exported = _run("export", "ubo2003", imported, "--out", tmp_path / "o", "--from-material")
    for result in (viewed, exported):
        assert result.exit_code in (1, 2)
        assert "material/btf: basis holds NaN or inf (1 of" in _said(result)
    assert not picture.exists() and not (tmp_path / "o").exists()
