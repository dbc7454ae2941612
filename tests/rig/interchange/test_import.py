"""Importing a UBO2003 folder or a plain folder of frames into an archive."""

import cv2
import numpy as np
import pytest

from rig.archive import Archive
from rig.interchange import (
    NORMTEXTURE_CAMERA,
    InterchangeError,
    import_folder,
    imported_normtextures,
    srgb_decode,
    to_srgb,
    write_image,
)
from tests.rig.interchange.conftest import LIGHTS, SIZE, VIEWS, normtexture, write_ubo_folder


def test_ubo2003_frames_arrive_linear_with_their_directions(tmp_path):
    report = import_folder(write_ubo_folder(tmp_path / "ubo"), tmp_path / "a.zarr", sample_mm=50)
    assert (report.frames, report.views, report.lights) == (15, 3, 5)
    assert (report.layout, report.encoding, report.gaps) == ("ubo2003", "srgb", ())
    with Archive.open(tmp_path / "a.zarr") as archive:
        assert imported_normtextures(archive.plan)
        assert "sRGB" in archive.plan["frames"]["colour_space"]
        assert archive.rig_config["holder"]["sample_mm"] == 50
        pairs = {}
        for step in archive.step_table():
            view = step.views_deg[NORMTEXTURE_CAMERA]
            pairs[(view, step.light_deg)] = archive.read_frame(step.index, NORMTEXTURE_CAMERA)
    assert set(pairs) == {(v, light) for v in VIEWS for light in LIGHTS}
    view, light = VIEWS[2], LIGHTS[4]
    frame = pairs[(view, light)]
    assert frame.dtype == np.float32 and frame.shape == (SIZE, SIZE, 3)
    expected = srgb_decode(to_srgb(normtexture(view, light)) / 255.0)
    np.testing.assert_allclose(frame, expected, atol=1e-6)
    # the sRGB encoding's 8 bits lose at most half a code: relative error ≤ 1/255 / slope
    np.testing.assert_allclose(frame, normtexture(view, light), atol=0.0055)


def test_jpg_names_import_too(tmp_path):
    folder = write_ubo_folder(tmp_path / "ubo", views=VIEWS[:1], suffix=".jpg")
    report = import_folder(folder, tmp_path / "a.zarr", sample_mm=50)
    assert report.frames == len(LIGHTS)


def test_a_partial_set_imports_with_its_gaps(tmp_path):
    folder = write_ubo_folder(tmp_path / "ubo", skip={(VIEWS[0], LIGHTS[3])})
    report = import_folder(folder, tmp_path / "a.zarr", sample_mm=50)
    assert report.frames == 14
    assert report.gaps == ("view (0°, 0°): 1 of 5 lights missing: (30°, 240°)",)
    with Archive.open(tmp_path / "a.zarr") as archive:
        assert archive.plan["source"]["gaps"] == list(report.gaps)


def test_an_image_of_another_size_is_named_and_no_archive_is_left(tmp_path):
    folder = write_ubo_folder(tmp_path / "ubo")
    odd = sorted((folder / "tv015_pv060").iterdir())[2]
    cv2.imwrite(str(odd), np.zeros((16, 32, 3), np.uint8))
    with pytest.raises(InterchangeError, match="every image of a data set has one size") as err:
        import_folder(folder, tmp_path / "a.zarr", sample_mm=50)
    assert odd.name in str(err.value) and "32×16×3 uint8" in str(err.value)
    assert not (tmp_path / "a.zarr").exists()


def test_an_image_of_another_pixel_type_is_named(tmp_path):
    folder = write_ubo_folder(tmp_path / "ubo")
    odd = sorted((folder / "tv030_pv090").iterdir())[0]
    write_image(odd, np.zeros((SIZE, SIZE, 3), np.uint16))
    with pytest.raises(InterchangeError, match="one size and pixel type") as err:
        import_folder(folder, tmp_path / "a.zarr", sample_mm=50)
    assert f"{odd.name}: 32×32×3 uint16 pixels, but" in str(err.value)


def test_a_file_that_is_no_image_is_named(tmp_path):
    folder = write_ubo_folder(tmp_path / "ubo")
    broken = sorted((folder / "tv000_pv000").iterdir())[1]
    broken.write_bytes(b"not a png")
    with pytest.raises(InterchangeError, match="unreadable") as err:
        import_folder(folder, tmp_path / "a.zarr", sample_mm=50)
    assert broken.name in str(err.value)


def test_an_existing_archive_is_refused(tmp_path):
    (tmp_path / "a.zarr").mkdir()
    with pytest.raises(InterchangeError, match="already exists"):
        import_folder(write_ubo_folder(tmp_path / "ubo"), tmp_path / "a.zarr", sample_mm=50)


def _plain_folder(tmp_path, table: str, text: str, dtype="uint16"):
    folder = tmp_path / "plain"
    folder.mkdir()
    for k in range(3):
        linear = normtexture(VIEWS[0], LIGHTS[k])
        if dtype == "float32":
            write_image(folder / f"f{k}.exr", linear)
        else:
            write_image(folder / f"f{k}.png", np.round(linear * 65535).astype(np.uint16))
    (folder / table).write_text(text)
    return folder


CSV = (
    "file,light_theta_deg,light_phi_deg,view_theta_deg,view_phi_deg\n"
    "f0.png,0,0,0,0\nf1.png,30,0,0,0\nf2.png,30,120,0,0\n"
)
TOML = "".join(
    f'[[frame]]\nfile = "f{k}.exr"\nlight_deg = [{t}, {p}]\nview_deg = [0, 0]\n'
    for k, (t, p) in enumerate(LIGHTS[:3])
)


@pytest.mark.parametrize(("table", "text", "dtype"), [
    ("directions.csv", CSV, "uint16"), ("directions.toml", TOML, "float32"),
])  # fmt: skip
def test_a_plain_folder_with_a_directions_table(tmp_path, table, text, dtype):
    folder = _plain_folder(tmp_path, table, text, dtype)
    report = import_folder(folder, tmp_path / "a.zarr", sample_mm=50)
    assert (report.layout, report.encoding, report.lights) == ("folder", "linear", 3)
    with Archive.open(tmp_path / "a.zarr") as archive:
        steps = archive.step_table()
        assert [s.light_deg for s in steps] == list(LIGHTS[:3])
        frame = archive.read_frame(steps[2].index, NORMTEXTURE_CAMERA)
    np.testing.assert_allclose(frame, normtexture(VIEWS[0], LIGHTS[2]), atol=1e-4)


@pytest.mark.parametrize(
    ("text", "complaint"),
    [
        (CSV.replace("30,120", "abc,120"), r"row 4: light = \('abc', '120'\)"),
        (CSV.replace("f2.png", "f9.png"), "file 'f9.png' does not exist"),
        (CSV.replace("f2.png,30,120,0,0\n", ""), "f2.png: not listed in directions.csv"),
        (CSV.replace("view_phi_deg", "phi"), "header"),
        (CSV.replace("30,0,0,0", "95,0,0,0"), "0 ≤ θ ≤ 90"),
    ],
)
def test_a_bad_directions_table_names_the_row_or_file(tmp_path, text, complaint):
    folder = _plain_folder(tmp_path, "directions.csv", text)
    with pytest.raises(InterchangeError, match=complaint):
        import_folder(folder, tmp_path / "a.zarr", sample_mm=50)
    assert not (tmp_path / "a.zarr").exists()
