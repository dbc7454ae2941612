"""PNG (sRGB, exposure) and EXR (float) output of rendered images."""

import cv2
import numpy as np
import OpenEXR
import pytest

from render import RenderError
from render.output import to_srgb8, write_exr, write_png


def test_srgb_encoding_at_known_points():
    linear = np.array([[[0.0, 0.0031308, 0.18], [0.5, 1.0, 4.0]]], np.float32)
    # IEC 61966-2-1: 0.0031308 → 0.04045; 18 % grey → 0.4614; 0.5 → 0.7354; ≥ 1 → 1.
    expected = np.round(np.array([[[0.0, 0.04045, 0.46135], [0.73536, 1.0, 1.0]]]) * 255)
    np.testing.assert_array_equal(to_srgb8(linear), expected.astype(np.uint8))
    # One stop of exposure doubles the linear value: 0.25 at +1 EV encodes as 0.5.
    np.testing.assert_array_equal(
        to_srgb8(np.full((1, 1, 3), 0.25, np.float32), exposure_ev=1.0), to_srgb8(
            np.full((1, 1, 3), 0.5, np.float32))
    )  # fmt: skip


def test_png_is_rgb_and_exr_keeps_floats(tmp_path):
    image = np.zeros((4, 5, 3), np.float32)
    image[..., 0] = np.linspace(0.0, 6e4, 20).reshape(4, 5)  # HDR in red only
    png = cv2.imread(str(write_png(tmp_path / "x.png", image)))
    assert png[..., 2].max() == 255 and png[..., :2].max() == 0  # red in the red channel
    with OpenEXR.File(str(write_exr(tmp_path / "x.exr", image))) as exr:
        back = exr.channels()["RGB"].pixels
    np.testing.assert_array_equal(back, image)


def test_bad_output_paths_and_images_are_named(tmp_path):
    image = np.zeros((2, 2, 3), np.float32)
    with pytest.raises(RenderError, match=r"x\.jpg: a PNG"):
        write_png(tmp_path / "x.jpg", image)
    with pytest.raises(RenderError, match="does not exist"):
        write_exr(tmp_path / "missing" / "x.exr", image)
    with pytest.raises(RenderError, match=r"\(H, W, 3\)"):
        write_png(tmp_path / "x.png", np.zeros((2, 2)))
    with pytest.raises(RenderError, match="exposure_ev"):
        to_srgb8(image, exposure_ev=np.inf)
