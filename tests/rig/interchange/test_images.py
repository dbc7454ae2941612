"""Image files both ways: pixels come back unchanged; what cannot be written is named."""

import numpy as np
import pytest

from rig.interchange import InterchangeError, InterchangeWriteError, read_image, write_image

RNG = np.random.default_rng(3)


@pytest.mark.parametrize(
    ("name", "pixels"),
    [
        ("a.png", RNG.integers(0, 256, (5, 7, 3), dtype=np.uint8)),
        ("b.png", RNG.integers(0, 65536, (5, 7, 1), dtype=np.uint16)),
        ("c.tif", RNG.integers(0, 65536, (5, 7, 3), dtype=np.uint16)),
        ("d.png", RNG.integers(0, 256, (5, 7, 4), dtype=np.uint8)),
        ("e.exr", RNG.normal(0, 100, (5, 7, 3)).astype(np.float32)),
        ("f.exr", RNG.normal(0, 1, (5, 7, 1)).astype(np.float32)),
    ],
)
def test_pixels_round_trip_unchanged(tmp_path, name, pixels):
    back = read_image(write_image(tmp_path / name, pixels))
    assert back.dtype == pixels.dtype
    np.testing.assert_array_equal(back, pixels)


@pytest.mark.parametrize(
    ("name", "pixels", "complaint"),
    [
        ("a.png", np.zeros((4, 4, 3), np.float32), "write uint8/uint16 pixels as .png"),
        ("a.exr", np.full((4, 4, 3), np.nan, np.float32), "NaN or inf"),
        ("a.png", np.zeros((4, 4, 2), np.uint8), "C = 1, 3, 4"),
    ],
)
def test_what_cannot_be_written_is_named(tmp_path, name, pixels, complaint):
    with pytest.raises(InterchangeError, match=complaint) as err:
        write_image(tmp_path / name, pixels)
    assert name in str(err.value)


def test_a_failed_write_is_a_failure_naming_the_file_not_bad_input(tmp_path):
    with pytest.raises(InterchangeWriteError, match="could not be written") as err:
        write_image(tmp_path / "missing" / "a.png", np.zeros((4, 4, 3), np.uint8))
    assert "missing/a.png" in str(err.value) and not isinstance(err.value, InterchangeError)


def test_a_non_image_is_named(tmp_path):
    (tmp_path / "notes.txt").write_text("x")
    with pytest.raises(InterchangeError, match=r"notes\.txt: not an image file"):
        read_image(tmp_path / "notes.txt")
    (tmp_path / "broken.exr").write_bytes(b"nope")
    with pytest.raises(InterchangeError, match=r"broken\.exr: not a readable OpenEXR"):
        read_image(tmp_path / "broken.exr")
