"""A material read whole: from an archive's material/ group, from a standalone store
written by export_material, and the errors that name what is wrong."""

import json

import numpy as np
import pytest

from rig.archive import Archive, FrameFormat
from rig.config import default_rig_config
from rig.material import MaterialError, export_material, read_material
from tests.rig.material.conftest import (
    SAMPLE_MM,
    N,
    make_archive,
    mdf,
    pca_model,
    ps_view,
    svd_model,
)


def _assert_same(a, b):
    assert (a.sample_mm, a.size, a.btf_units) == (b.sample_mm, b.size, b.btf_units)
    assert type(a.btf) is type(b.btf)
    for name in ("view_dirs_deg", "light_dirs_deg", "weights", "mean", "basis", "rank"):
        np.testing.assert_array_equal(getattr(a.btf, name), getattr(b.btf, name))
    np.testing.assert_array_equal(a.btf_slot_valid, b.btf_slot_valid)
    assert sorted(a.ps) == sorted(b.ps)
    for name, view in a.ps.items():
        other = b.ps[name]
        assert (view.view_deg, view.attrs) == (other.view_deg, other.attrs)
        for key in ("normals", "albedo", "valid", "reason", "height_mm"):
            np.testing.assert_array_equal(getattr(view, key), getattr(other, key))
    for key in ("distance_mm", "view_dirs_deg", "reason", "count"):
        np.testing.assert_array_equal(getattr(a.mdf, key), getattr(b.mdf, key))
    assert a.mdf.attrs == b.mdf.attrs


def test_an_archive_material_reads_whole(archive):
    material = read_material(archive)
    assert material.source == archive
    assert material.sample_mm == SAMPLE_MM and material.size == N
    assert material.btf_units == "relative radiance"
    np.testing.assert_array_equal(material.btf.basis, pca_model().basis)
    assert material.btf_slot_valid.tolist() == [True, True, True]
    assert material.frontal_ps().name == "cam0_tt000.0"  # θ 2° beats θ 30°
    np.testing.assert_array_equal(material.mdf.distance_mm, mdf().distance_mm)
    provenance = material.provenance
    assert provenance["calibration_version"] == 1
    assert provenance["calibration"]["cameras"]["archive"] == "charuco.zarr"
    assert provenance["corrections"] == {"cameras": ["cam0"], "laser": []}
    assert sorted(provenance["results"]) == ["btf", "mdf", "ps"]
    assert "numpy" in provenance["software"]["archive"]


def test_export_then_read_gives_the_archive_material(archive, tmp_path):
    out = export_material(archive, tmp_path / "m.zarr")
    exported = read_material(out)
    _assert_same(exported, read_material(archive))
    assert exported.source == out
    assert exported.provenance["source_archive"] == str(archive.resolve())
    assert set(exported.provenance["software"]) == {"archive", "export"}
    # no frames, no journal: only the material groups and the root document
    assert sorted(p.name for p in out.iterdir()) == ["btf", "mdf", "ps", "zarr.json"]
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []


def test_export_refuses_an_existing_path_and_a_non_archive(archive, tmp_path):
    (tmp_path / "taken.zarr").mkdir()
    with pytest.raises(MaterialError, match=r"taken\.zarr: already exists"):
        export_material(archive, tmp_path / "taken.zarr")
    with pytest.raises(MaterialError, match="not a session archive to export from"):
        export_material(tmp_path / "taken.zarr", tmp_path / "new.zarr")
    assert not (tmp_path / "new.zarr").exists()


def test_svd_btf_alone_is_a_material(tmp_path):
    material = read_material(make_archive(tmp_path / "s.zarr", btf=svd_model()))
    assert material.btf.rank == 2 and material.ps == {} and material.mdf is None
    assert material.frontal_ps() is None


def test_ps_alone_sets_the_size_and_the_only_view_is_frontal(tmp_path):
    material = read_material(make_archive(tmp_path / "s.zarr", ps=[ps_view("v", (40.0, 0.0))]))
    assert material.btf is None and material.btf_slot_valid is None and material.size == N
    assert material.frontal_ps().name == "v"


def test_old_ps_views_get_their_direction_from_the_rig_config(tmp_path):
    path = tmp_path / "old.zarr"
    config = default_rig_config().model_dump(mode="json")
    view = ps_view("cam3_tt030.0")
    cameras = {"cam3": FrameFormat(4, 4, 1, "uint8")}
    with (
        Archive.create(path, plan={}, rig_config=config, cameras=cameras, fsync=False) as archive,
        archive.replace_material("ps") as group,  # the layout written before versioning
    ):
        sub = group.create_group(view.name)
        for key in ("normals", "albedo", "valid", "reason", "height_mm"):
            sub.create_array(key, data=getattr(view, key))
        sub.attrs.update(camera="cam3", turntable_deg=30.0, steps=[0])
    material = read_material(path)
    assert material.sample_mm == 100.0  # the default holder
    # cam3 sits at 45° on the arc; turning the sample by 30° puts it at φ = −30°
    np.testing.assert_allclose(material.ps[view.name].view_deg, (45.0, 330.0), atol=1e-9)


def test_paths_that_hold_no_material_are_named(tmp_path):
    with pytest.raises(MaterialError, match=r"no zarr\.json here"):
        read_material(tmp_path)
    (tmp_path / "zarr.json").write_text(json.dumps({"zarr_format": 3, "node_type": "group"}))
    with pytest.raises(MaterialError, match="neither a session archive nor a material store"):
        read_material(tmp_path)
    empty = make_archive(tmp_path / "empty.zarr")
    message = r"empty\.zarr/material: holds none of btf, ps, mdf, pbr"
    with pytest.raises(MaterialError, match=message):
        read_material(empty)


def test_a_store_of_another_version_is_refused(archive, tmp_path):
    out = export_material(archive, tmp_path / "m.zarr")
    document = json.loads((out / "zarr.json").read_text())
    document["attributes"]["version"] = 4
    (out / "zarr.json").write_text(json.dumps(document))
    with pytest.raises(MaterialError, match="store version 4; this btfrig reads version 1"):
        read_material(out)


def test_a_damaged_group_in_the_archive_is_named_with_its_path(archive):
    import zarr

    group = zarr.open_group(archive / "material" / "mdf", mode="r+")
    group.attrs["version"] = 9
    with pytest.raises(MaterialError, match=r"s\.zarr/material/mdf: mdf group has version 9"):
        read_material(archive)
