"""`rig export material`: a store that reads back as the archive's material; bad paths
exit 2 naming them, a material that cannot be exported exits 1; never a traceback."""

import numpy as np
import pytest
import zarr
from typer.testing import CliRunner

from orchestrator.cli import app
from rig.archive import Archive
from rig.material import MaterialError, export_material, read_material
from tests.rig.material.conftest import make_archive, mdf, ps_view

runner = CliRunner()


@pytest.fixture
def archive(tmp_path):
    return make_archive(tmp_path / "s.zarr", ps=[ps_view("cam0_tt000.0")], mdf=mdf())


def test_export_material_writes_a_store(archive, tmp_path):
    out = tmp_path / "m.zarr"
    result = runner.invoke(app, ["export", "material", str(archive), "--out", str(out)])
    assert result.exit_code == 0, result.output
    assert str(out) in result.output
    material = read_material(out)
    np.testing.assert_array_equal(material.mdf.distance_mm, mdf().distance_mm)
    assert list(material.ps) == ["cam0_tt000.0"]


@pytest.mark.parametrize(
    ("source", "out", "named"),
    [
        ("nowhere.zarr", "m.zarr", "nowhere.zarr: not a session archive"),
        ("s.zarr", "s.zarr", "s.zarr: lies in or around the archive"),
        ("s.zarr", "s.zarr/material/x.zarr", "x.zarr: lies in or around the archive"),
        ("s.zarr", "s.zarr/frames/cam0/c.999.0.0.0", "c.999.0.0.0: lies in or around"),
        ("s.zarr/material", "s.zarr", "s.zarr: lies in or around the archive"),
        ("s.zarr", "out.zarr", "out.zarr: already exists"),
    ],
)
def test_bad_paths_exit_2_naming_them(archive, tmp_path, source, out, named):
    (tmp_path / "out.zarr").mkdir()
    args = ["export", "material", str(tmp_path / source), "--out", str(tmp_path / out)]
    result = runner.invoke(app, args)
    assert result.exit_code == 2
    assert named in " ".join(result.output.split())
    assert "Traceback" not in result.output
    Archive.open(archive).close()  # nothing was written into it
    assert not (archive / "material" / "x.zarr").exists()
    assert not (archive / "frames" / "cam0" / "c.999.0.0.0").exists()


def test_the_library_refuses_a_store_inside_the_archive(archive):
    with pytest.raises(MaterialError, match=r"x\.zarr: lies in or around the archive"):
        export_material(archive, archive / "material" / "x.zarr")
    assert not (archive / "material" / "x.zarr").exists()


def test_a_material_that_cannot_be_read_exits_1(archive, tmp_path):
    zarr.open_group(archive / "material" / "ps", mode="r+").attrs["version"] = 5
    args = ["export", "material", str(archive), "--out", str(tmp_path / "m.zarr")]
    result = runner.invoke(app, args)
    assert result.exit_code == 1
    assert "ps group has version 5" in " ".join(result.output.split())
    assert not (tmp_path / "m.zarr").exists()
    assert result.exception is None or isinstance(result.exception, SystemExit)
