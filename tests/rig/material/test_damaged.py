"""A damaged material is refused when read, naming the group and the array: NaN or inf
values (they would render black), a dtype of another kind, a chunk that cannot be decoded."""

import numpy as np
import pytest

from rig.material import MaterialError, read_material
from tests.rig.material.conftest import make_archive, mdf, pca_model, ps_view


def _replace(archive, group: str, name: str, change) -> None:
    """Store ``change(old values)`` as the array ``group/name`` of the archive's material."""
    import zarr

    where = zarr.open_group(archive / "material" / group, mode="r+")
    values = change(where[name][...])
    del where[name]
    where.create_array(name, data=values)


def _nan_at_first(values):
    values = values.copy()
    values.reshape(-1)[0] = np.nan
    return values


#: zarr warns when it stores or reads a string array (its v3 spec has no such type)
UNSPECIFIED_DTYPE = pytest.mark.filterwarnings("ignore::zarr.errors.UnstableSpecificationWarning")


@UNSPECIFIED_DTYPE
@pytest.mark.parametrize(
    ("name", "change", "complaint"),
    [
        ("basis", _nan_at_first, r"basis holds NaN or inf \(1 of 1152 values\)"),
        ("mean", lambda v: np.full_like(v, np.nan), r"mean holds NaN or inf \(576 of 576 values\)"),
        ("weights", lambda v: np.full_like(v, np.inf), r"weights holds NaN or inf \(24 of 24"),
        ("basis", lambda v: v.astype(np.int64), "basis has dtype int64; expected float"),
        ("weights", lambda v: v.astype(str), "weights has dtype <U.*; expected float"),
        ("rank", lambda v: v + 7, r"rank \(int32\) must hold whole numbers in 0…2"),
        ("view_dirs_deg", lambda v: np.full(v.shape, "north"), "view_dirs_deg: expected"),
    ],
)
def test_a_damaged_btf_array_is_named(tmp_path, name, change, complaint):
    archive = make_archive(tmp_path / "s.zarr", btf=pca_model())
    _replace(archive, "btf", name, change)
    with pytest.raises(MaterialError, match=r"s\.zarr/material/btf: " + complaint):
        read_material(archive)


@UNSPECIFIED_DTYPE
@pytest.mark.parametrize(
    ("group", "name", "complaint"),
    [
        ("ps", "albedo", "ps/cam0_tt000.0: albedo has dtype <U"),
        ("ps", "normals", "ps/cam0_tt000.0: normals has dtype <U"),
        ("mdf", "distance_mm", "mdf: distance_mm has dtype <U"),
    ],
)
def test_a_string_array_in_ps_or_mdf_is_named(tmp_path, group, name, complaint):
    archive = make_archive(tmp_path / "s.zarr", ps=[ps_view("cam0_tt000.0")], mdf=mdf())
    array_group = group if group == "mdf" else f"{group}/cam0_tt000.0"
    _replace(archive, array_group, name, lambda v: v.astype(str))
    with pytest.raises(MaterialError, match=r"s\.zarr/material/" + complaint):
        read_material(archive)


def test_a_truncated_chunk_is_named_with_its_array(tmp_path):
    archive = make_archive(tmp_path / "s.zarr", btf=pca_model())
    chunk = next(p for p in (archive / "material" / "btf" / "basis").rglob("*")
                 if p.is_file() and p.name != "zarr.json")  # fmt: skip
    chunk.write_bytes(chunk.read_bytes()[: chunk.stat().st_size // 2])
    with pytest.raises(MaterialError, match=r"material/btf: array 'basis' cannot be read"):
        read_material(archive)
