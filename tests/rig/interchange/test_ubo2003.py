"""The UBO2003 layout: names both ways, listing a folder with its gaps, bad entries named."""

import numpy as np
import pytest

from rig.geometry import Sampling
from rig.interchange import (
    InterchangeError,
    list_ubo2003,
    srgb_decode,
    to_srgb,
    ubo2003_file,
    ubo2003_view_folder,
    write_ubo2003,
)
from tests.rig.interchange.conftest import LIGHTS, VIEWS, write_ubo_folder


def test_names_follow_the_layout():
    assert ubo2003_view_folder((15, 60)) == "tv015_pv060"
    assert ubo2003_file(7, (75.0, 345.0), (0, 0), suffix=".jpg") == (
        "00007 tl075 pl345 tv000 pv000.jpg"
    )
    assert ubo2003_view_folder((30.2, 360.0)) == "tv030_pv000"


def test_a_complete_folder_lists_every_view_and_light(tmp_path):
    listing = list_ubo2003(write_ubo_folder(tmp_path / "ubo"))
    assert len(listing.frames) == len(VIEWS) * len(LIGHTS)
    assert set(listing.views_deg) == set(VIEWS)
    assert set(listing.lights_deg) == set(LIGHTS)
    assert listing.gaps == ()
    first = listing.frames[0]
    assert (first.index, first.light_deg, first.view_deg) == (0, LIGHTS[0], VIEWS[0])


def test_a_view_with_fewer_images_is_listed_as_a_gap(tmp_path):
    skip = {(VIEWS[1], LIGHTS[2]), (VIEWS[1], LIGHTS[4])}
    listing = list_ubo2003(write_ubo_folder(tmp_path / "ubo", skip=skip))
    assert len(listing.frames) == len(VIEWS) * len(LIGHTS) - 2
    assert len(listing.gaps) == 1
    assert "view (15°, 60°): 2 of 5 lights missing: (30°, 120°), (60°, 30°)" in listing.gaps[0]


@pytest.mark.parametrize(
    ("name", "complaint"),
    [
        ("tv000_pv000/00000 tl000 pl000 tv000 pv000.txt", "not a UBO2003 image name"),
        ("tv000_pv000/img_0001.png", "not a UBO2003 image name"),
        ("tv000_pv000/00009 tl000 pl000 tv015 pv060.png", "names view tv015 pv060"),
        ("notes.txt", "not a UBO2003 view folder"),
    ],
)
def test_a_stray_entry_is_named(tmp_path, name, complaint):
    root = write_ubo_folder(tmp_path / "ubo")
    (root / name).write_bytes(b"x")
    with pytest.raises(InterchangeError, match=complaint) as err:
        list_ubo2003(root)
    assert name.split("/")[-1] in str(err.value)


def test_an_empty_folder_says_so(tmp_path):
    with pytest.raises(InterchangeError, match="no images in the UBO2003 layout"):
        list_ubo2003(tmp_path)


def test_srgb_8_bit_codes_survive_decoding_and_encoding():
    codes = np.arange(256, dtype=np.uint8)
    np.testing.assert_array_equal(to_srgb(srgb_decode(codes / 255.0)), codes)
    codes16 = np.arange(0, 65536, 7, dtype=np.uint16)
    np.testing.assert_array_equal(to_srgb(srgb_decode(codes16 / 65535.0), dtype="uint16"), codes16)


def test_views_and_lights_missing_from_the_seed_sampling_are_listed(tmp_path):
    h2 = [tuple(map(float, d)) for d in Sampling.named("H2").directions]
    views, lights = h2[:3], h2[:2] + h2[3:5]  # the first 3 views; light (15°, 60°) left out
    listing = list_ubo2003(write_ubo_folder(tmp_path / "ubo", views, lights))
    assert listing.gaps[0].startswith(
        "78 of the 81 views of the H2 sampling missing: (15°, 120°), (15°, 180°)"
    )
    assert listing.gaps[1] == (
        "77 of the 81 lights of the H2 sampling missing: (15°, 60°), (15°, 240°), (15°, 300°), "
        "(30°, 0°), (30°, 30°), (30°, 60°) and 71 more"
    )
    assert len(listing.gaps) == 2


def test_views_that_share_a_folder_name_are_refused(tmp_path):
    views = np.array([[30.2, 90.0], [29.8, 90.0]])
    with pytest.raises(InterchangeError, match=r"share the UBO2003 folder tv030_pv090"):
        write_ubo2003(tmp_path, views, [(0.0, 0.0)], lambda j, i: np.zeros((2, 2, 3)),
                      white=1.0, manifest={})  # fmt: skip
    assert list(tmp_path.iterdir()) == []
