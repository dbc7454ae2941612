"""The material's pbr group: written and read back whole, and what it refuses."""

import dataclasses

import numpy as np
import pytest
import zarr

from rig.material import MaterialError, PbrMaps, read_pbr, write_pbr
from tests.rig.material.conftest import pbr_maps as _maps


def _group(tmp_path):
    return zarr.open_group(tmp_path / "m.zarr", mode="w").create_group("pbr")


def test_round_trip_keeps_every_map(tmp_path):
    group = _group(tmp_path)
    maps = _maps()
    write_pbr(group, maps)
    back = read_pbr(group)
    for field in dataclasses.fields(PbrMaps):
        if field.name != "attrs":
            np.testing.assert_allclose(
                getattr(back, field.name), getattr(maps, field.name), rtol=1e-6
            )
    assert back.attrs == {"psnr_db": 31.5}
    assert group.attrs["flag_bits"]["NO_SPECULAR"] == 4
    assert group.attrs["version"] == 1


@pytest.mark.parametrize(
    ("changes", "message"),
    [({"roughness": np.full((4, 4), np.nan)}, "roughness holds NaN"),
     ({"specular": np.full((4, 4), 1.5)}, r"specular spans .*expected \[0, 1\]"),
     ({"height_mm": np.zeros((3, 4))}, r"height_mm has shape \(3, 4\), expected \(4, 4\)"),
     ({"sheen_colour": np.zeros((4, 4, 1))}, "base_colour .* and sheen_colour .* differ"),
     ({"normal": np.zeros((4, 4, 3))}, "normal holds vectors of length"),
     ({"flags": np.full((4, 4), 300)}, r"flags \(int64\) must hold whole numbers in 0..255")],
)  # fmt: skip
def test_bad_maps_are_refused_by_name(tmp_path, changes, message):
    with pytest.raises(MaterialError, match=message):
        write_pbr(_group(tmp_path), _maps(**changes))


def test_an_unknown_version_is_named(tmp_path):
    group = _group(tmp_path)
    write_pbr(group, _maps())
    group.attrs["version"] = 9
    with pytest.raises(MaterialError, match="pbr group has version 9; this btfrig reads version 1"):
        read_pbr(group)
