"""Bad data sets are refused at import, naming the file and what would be valid, and
leave no archive behind: directions below the horizon, oversized or damaged image
headers, transparent or non-finite pixels, unreadable tables and manifests."""

import struct
import zlib

import cv2
import numpy as np
import pytest

from rig.interchange import InterchangeError, image_size, import_folder, write_image
from tests.rig.interchange.conftest import LIGHTS, VIEWS, write_ubo_folder

CSV_HEADER = "file,light_theta_deg,light_phi_deg,view_theta_deg,view_phi_deg\n"


def _png_header(width: int, height: int) -> bytes:
    """The first bytes of an 8-bit RGB PNG of ``width`` × ``height`` (no pixel data)."""
    ihdr = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    chunk = b"IHDR" + ihdr
    return (
        b"\x89PNG\r\n\x1a\n" + struct.pack(">I", len(ihdr)) + chunk
        + struct.pack(">I", zlib.crc32(chunk)) + b"\x00\x00\x00\x00IDAT\x35\xaf\x06\x1e"
    )  # fmt: skip


def _refused(folder, tmp_path, complaint: str) -> None:
    with pytest.raises(InterchangeError, match=complaint):
        import_folder(folder, tmp_path / "a.zarr")
    assert not (tmp_path / "a.zarr").exists()


def _image(path, pixels) -> None:
    cv2.imwrite(str(path), np.ascontiguousarray(pixels))


@pytest.mark.parametrize(
    ("view", "name", "complaint"),
    [
        ("tv120_pv000", "00000 tl000 pl000 tv120 pv000.png", r"tv120_pv000: view = \(120°"),
        ("tv999_pv000", "00000 tl000 pl000 tv999 pv000.png", r"tv999_pv000: view = \(999°"),
        ("tv000_pv000", "00009 tl135 pl000 tv000 pv000.png", r"tl135 .*: light = \(135°"),
        ("tv000_pv000", "00009 tl999 pl000 tv000 pv000.png", r"tl999 .*: light = \(999°"),
    ],
)
def test_a_direction_below_the_horizon_is_named(tmp_path, view, name, complaint):
    folder = write_ubo_folder(tmp_path / "ubo", views=VIEWS[:1])
    (folder / view).mkdir(exist_ok=True)
    _image(folder / view / name, np.zeros((32, 32, 3), np.uint8))
    _refused(folder, tmp_path, complaint + ".*below the horizon")


@pytest.mark.parametrize("white", ["1" + "0" * 400, "NaN", "-1", "true", '"bright"'])
def test_a_manifest_white_that_is_no_finite_positive_number_is_named(tmp_path, white):
    folder = write_ubo_folder(tmp_path / "ubo", views=VIEWS[:1])
    (folder / "manifest.json").write_text('{"white": ' + white + "}")
    _refused(folder, tmp_path, "manifest.json: white = .*expected a finite number > 0")


@pytest.mark.parametrize(("width", "height"), [(16384, 16384), (100000, 100000), (0, 32)])
def test_an_image_header_claiming_too_many_pixels_is_refused_before_decoding(
    tmp_path, width, height
):
    folder = write_ubo_folder(tmp_path / "ubo", views=VIEWS[:1])
    big = folder / "tv000_pv000" / "00009 tl045 pl000 tv000 pv000.png"
    big.write_bytes(_png_header(width, height))
    _refused(folder, tmp_path, f"tl045 .*: {width}×{height} pixels; images of 1 to 67108864")


@pytest.mark.parametrize("suffix", [".png", ".jpg", ".tif", ".hdr", ".exr"])
def test_the_size_is_read_from_each_header(tmp_path, suffix):
    path = tmp_path / f"x{suffix}"
    pixels = np.zeros((37, 53, 3), np.float32 if suffix in (".hdr", ".exr") else np.uint8)
    write_image(path, pixels) if suffix == ".exr" else _image(path, pixels)
    assert image_size(path) == (53, 37)


def test_a_transparent_rgba_set_is_refused_and_an_opaque_one_imported_as_rgb(tmp_path):
    folder = tmp_path / "ubo"
    (folder / "tv000_pv000").mkdir(parents=True)
    for index, light in enumerate(LIGHTS):
        pixels = np.full((32, 32, 4), 200, np.uint8)
        pixels[:, :, 3] = 255
        _image(folder / "tv000_pv000" / f"{index:05d} tl{light[0]:03.0f} pl{light[1]:03.0f} "
               "tv000 pv000.png", pixels)  # fmt: skip
    report = import_folder(folder, tmp_path / "opaque.zarr")
    assert report.shape == (32, 32, 3)
    first = folder / "tv000_pv000" / "00000 tl000 pl000 tv000 pv000.png"
    pixels = np.full((32, 32, 4), 200, np.uint8)
    pixels[0, 0, 3] = 0
    _image(first, pixels)
    _refused(folder, tmp_path, "00000 tl000 .*: RGBA pixels with a transparent part")


@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_an_exr_holding_nan_or_inf_is_named(tmp_path, bad):
    import OpenEXR

    folder = tmp_path / "plain"
    folder.mkdir()
    pixels = np.full((8, 8, 3), 0.5, np.float32)
    pixels[2, 3, 1] = bad
    with OpenEXR.File({"type": OpenEXR.scanlineimage}, {"RGB": pixels}) as exr:
        exr.write(str(folder / "f0.exr"))  # write_image itself refuses non-finite pixels
    (folder / "directions.csv").write_text(CSV_HEADER + "f0.exr,0,0,0,0\n")
    _refused(folder, tmp_path, r"f0.exr: 1 of 192 values are NaN or inf")


def test_a_table_that_is_not_utf8_is_named_with_its_line(tmp_path):
    folder = tmp_path / "plain"
    folder.mkdir()
    _image(folder / "f0.png", np.zeros((8, 8, 3), np.uint8))
    (folder / "directions.csv").write_bytes(
        CSV_HEADER.encode() + b"f0.png,0,0,0,0\n\xff\xfe.png,0,0,0,0\n"
    )
    _refused(folder, tmp_path, r"directions.csv line 3: not UTF-8 text \(byte 0xff\)")


def test_a_csv_field_over_the_csv_limit_is_named_with_its_line(tmp_path):
    folder = tmp_path / "plain"
    folder.mkdir()
    _image(folder / "f0.png", np.zeros((8, 8, 3), np.uint8))
    (folder / "directions.csv").write_text(CSV_HEADER + "f0.png,0,0,0," + "0" * 140_000 + "\n")
    _refused(folder, tmp_path, r"directions.csv line 2: not a readable CSV row \(field larger")


def test_a_tiff_whose_directory_follows_its_pixels_is_sized(tmp_path):
    path = tmp_path / "big.tif"
    _image(path, np.random.default_rng(0).integers(0, 65535, (700, 900), np.uint16))
    assert int.from_bytes(path.read_bytes()[4:8], "little") > 4096  # the IFD is at the end
    assert image_size(path) == (900, 700)


@pytest.mark.parametrize("damage", [b"\xff\xd8\xff\xe0\x00\x00", b"\xff\xd8\xff\xe0\x00\x10JF"])
def test_a_damaged_jpeg_header_is_named(tmp_path, damage):
    path = tmp_path / "x.jpg"
    path.write_bytes(damage)
    with pytest.raises(InterchangeError, match=r"x\.jpg: unreadable"):
        image_size(path)
