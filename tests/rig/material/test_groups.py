"""Each group of the material format: written by its writer, read back by its reader;
bad versions, shapes and values named; groups written before the format was versioned
still read."""

import numpy as np
import pytest
import zarr

from rig.material import (
    NOT_RECORDED,
    FlatFieldMaps,
    LiveAppender,
    MaterialError,
    Radiometry,
    archive_flat_field_path,
    copy_flat_field,
    live_rows,
    read_btf,
    read_flat_field,
    read_live,
    read_mdf,
    read_ps,
    write_btf,
    write_flat_field,
    write_mdf,
    write_ps,
)
from tests.rig.material.conftest import N, mdf, pca_model, ps_view, svd_model


def group():
    return zarr.open_group(zarr.storage.MemoryStore(), mode="w", zarr_format=3)


@pytest.mark.parametrize("make", [pca_model, svd_model])
def test_btf_round_trip_keeps_model_slots_and_extra_attributes(make):
    model = make()
    g = group()
    slots = np.array([True, False, True])
    write_btf(g, model, units="relative radiance per second", slot_valid=slots,
              attrs={"flagged": [[1, 0, 7, "cam2", "TOO_FEW_MARKERS"]]})  # fmt: skip
    back = read_btf(g)
    assert type(back.model) is type(model)
    for name in ("view_dirs_deg", "light_dirs_deg", "weights", "singular_values"):
        np.testing.assert_allclose(getattr(back.model, name), getattr(model, name), rtol=1e-6)
    texture = "basis" if make is pca_model else "eigenmaps"
    np.testing.assert_array_equal(getattr(back.model, texture), getattr(model, texture))
    np.testing.assert_array_equal(back.slot_valid, slots)
    assert back.units == "relative radiance per second"
    assert back.attrs["flagged"] == [[1, 0, 7, "cam2", "TOO_FEW_MARKERS"]]
    assert g.attrs["format"] == "btfrig.material.btf" and g.attrs["version"] == 2
    assert back.radiometry == Radiometry() and not back.radiometry.applied


RECORD = Radiometry(
    linearised=("cam0",), flat_fielded=("L0", "L1"), calibration_version=3,
    sources={"response": "calibrations/response.zarr (2026-01-02T03:04:05+00:00)"},
    skipped={"cam2": "no response curve in the archive's calibration"},
)  # fmt: skip


def test_btf_records_its_radiometry_and_reads_version_1_as_not_recorded():
    g = group()
    write_btf(g, pca_model(), units="x", radiometry=RECORD)
    assert read_btf(g).radiometry == RECORD and RECORD.applied
    assert "radiometry" not in read_btf(g).attrs
    # version 1: the group as written before the record existed
    del g.attrs["radiometry"]
    g.attrs["version"] = 1
    back = read_btf(g)
    assert back.radiometry is NOT_RECORDED and not back.radiometry.applied
    assert back.model.weights.shape == pca_model().weights.shape


def test_ps_records_its_radiometry_per_view_and_reads_version_1_as_not_recorded():
    from dataclasses import replace

    g = group()
    write_ps(g, [replace(ps_view("a"), radiometry=RECORD), ps_view("b")])
    back = read_ps(g)
    assert back["a"].radiometry == RECORD and back["b"].radiometry == Radiometry()
    assert "radiometry" not in back["a"].attrs
    for name in ("a", "b"):
        del g[name].attrs["radiometry"]
    g.attrs["version"] = 1
    assert all(v.radiometry is NOT_RECORDED for v in read_ps(g).values())


@pytest.mark.parametrize(
    "value",
    [None, {"linearised": "cam0"}, {**RECORD.to_attrs(), "calibration_version": -1},
     {**RECORD.to_attrs(), "linearised": [3]}],
)  # fmt: skip
def test_a_bad_radiometry_record_is_named(value):
    g = group()
    write_btf(g, pca_model(), units="x")
    g.attrs["radiometry"] = value
    with pytest.raises(MaterialError, match="material/btf: attribute radiometry"):
        read_btf(g)


def test_btf_without_slot_valid_has_every_slot_valid():
    g = group()
    write_btf(g, pca_model(), units="relative radiance")
    del g["slot_valid"]
    assert read_btf(g).slot_valid.tolist() == [True, True, True]


def test_btf_errors_name_the_array_or_attribute():
    g = group()
    with pytest.raises(MaterialError, match=r"slot_valid.*\(3,\) bool"):
        write_btf(g, pca_model(), units="x", slot_valid=[1, 0, 1])
    with pytest.raises(MaterialError, match="format's own attributes"):
        write_btf(group(), pca_model(), units="x", attrs={"kind": "mine"})
    write_btf(g, pca_model(), units="x")
    g.attrs["version"] = 7
    with pytest.raises(MaterialError, match=r"material/btf: btf group has version 7; .* 1, 2"):
        read_btf(g)
    g.attrs["version"] = 2
    del g["weights"]
    g.create_array("weights", data=np.zeros((3, 4, 5), np.float32))
    with pytest.raises(MaterialError, match=r"weights has shape \(3, 4, 5\), expected \(3, 4, 2\)"):
        read_btf(g)


def test_btf_without_format_attributes_is_refused():
    g = group()
    write_btf(g, pca_model(), units="x")
    del g.attrs["format"], g.attrs["version"]
    with pytest.raises(MaterialError, match="no format/version attributes"):
        read_btf(g)


def test_ps_round_trip():
    views = [ps_view("cam0_tt000.0", (1.5, 10.0)), ps_view("cam3_tt090.0", None, seed=5)]
    g = group()
    write_ps(g, views, attrs={"method": "irls"})
    back = read_ps(g)
    assert list(back) == ["cam0_tt000.0", "cam3_tt090.0"]
    for view in views:
        got = back[view.name]
        for name in ("normals", "albedo", "valid", "reason", "height_mm"):
            np.testing.assert_array_equal(getattr(got, name), getattr(view, name))
        assert got.view_deg == view.view_deg and got.attrs == view.attrs
    assert g.attrs["method"] == "irls" and g.attrs["size"] == N


def test_ps_written_before_versioning_reads_as_version_0():
    # the layout the ps stage wrote before: arrays per view, no format/version, no view_deg
    view = ps_view("cam0_tt000.0")
    g = group()
    sub = g.create_group(view.name)
    for key in ("normals", "albedo", "valid", "reason", "height_mm"):
        sub.create_array(key, data=getattr(view, key))
    sub.attrs.update(camera="cam0", turntable_deg=0.0, steps=[1, 2], size=N, method="irls")
    g.attrs.update(stage="ps", size=N, method="irls")
    (got,) = read_ps(g).values()
    assert got.view_deg is None and got.attrs["camera"] == "cam0"
    np.testing.assert_array_equal(got.normals, view.normals)


@pytest.mark.parametrize(
    ("change", "match"),
    [
        (lambda v: {"normals": v.normals[:, :4]}, r"normals has shape \(8, 4, 3\)"),
        (lambda v: {"albedo": v.albedo[..., :2]}, "albedo has 2 channels"),
        (lambda v: {"valid": v.valid.astype(np.uint8)}, "valid has dtype uint8, expected bool"),
        (lambda v: {"height_mm": v.height_mm[:4]}, r"height_mm has shape \(4, 8\)"),
        (lambda v: {"height_mm": v.height_mm * np.nan}, "height_mm holds NaN"),
        (lambda v: {"normals": 2 * v.normals}, "expected unit vectors"),
        (lambda v: {"view_deg": (95.0, 0.0)}, r"view_deg = \(95.0, 0.0\)"),
    ],
)
def test_bad_ps_views_are_named(change, match):
    from dataclasses import replace

    view = ps_view("cam0_tt000.0")
    with pytest.raises(MaterialError, match=match):
        write_ps(group(), [replace(view, **change(view))])


def test_ps_views_must_share_the_grid_and_have_unique_names():
    from dataclasses import replace

    view = ps_view("a")
    small = replace(view, name="b", normals=view.normals[:4, :4], albedo=view.albedo[:4, :4],
                    valid=view.valid[:4, :4], reason=view.reason[:4, :4],
                    height_mm=view.height_mm[:4, :4])  # fmt: skip
    with pytest.raises(MaterialError, match=r"different texel grids N = \[4, 8\]"):
        write_ps(group(), [view, small])
    with pytest.raises(MaterialError, match="view names repeat"):
        write_ps(group(), [view, view])


def test_mdf_round_trip_and_old_layout():
    want = mdf()
    g = group()
    write_mdf(g, want)
    got = read_mdf(g)
    for name in ("distance_mm", "view_dirs_deg", "reason", "count"):
        np.testing.assert_array_equal(getattr(got, name), getattr(want, name))
    assert got.attrs == want.attrs
    np.testing.assert_allclose(got.coverage(), (want.distance_mm >= 0).mean(axis=(1, 2)))
    # the layout the mdf stage wrote before: same arrays, attributes without format/version
    old = group()
    for name in ("distance_mm", "reason", "count", "view_dirs_deg"):
        old.create_array(name, data=getattr(want, name))
    old.attrs.update(stage="mdf", size=N, peak="gaussian", unseen=-1.0, views=["a", "b"])
    assert read_mdf(old).attrs == {"stage": "mdf", "peak": "gaussian", "views": ["a", "b"]}
    old.attrs.update(format="btfrig.material.mdf", version=2)
    with pytest.raises(MaterialError, match="mdf group has version 2"):
        read_mdf(old)


def test_bad_mdf_is_named():
    from dataclasses import replace

    want = mdf()
    with pytest.raises(MaterialError, match=r"count has shape \(1, 8, 8\)"):
        write_mdf(group(), replace(want, count=want.count[:1]))
    with pytest.raises(MaterialError, match=r"≥ 0, or -1.0"):
        write_mdf(group(), replace(want, distance_mm=want.distance_mm - 5.0))
    with pytest.raises(MaterialError, match=r"count \(int64\) must hold whole numbers in 0\.\.255"):
        write_mdf(group(), replace(want, count=want.count.astype(np.int64) + 300))
    with pytest.raises(MaterialError, match="view_dirs_deg: 3 directions for 2"):
        write_mdf(group(), replace(want, view_dirs_deg=np.zeros((3, 2), np.float32)))
    g = group()
    write_mdf(g, want)
    g.attrs["format"] = "btfrig.material.ps"
    with pytest.raises(MaterialError, match=r"format = 'btfrig\.material\.ps', expected .*mdf"):
        read_mdf(g)


def _frames():
    rng = np.random.default_rng(0)
    for step in (3, 1, 2):
        for camera in ("cam0", "cam2"):
            header = {"step": step, "sub": 0, "camera": camera}
            yield header, {"stats.mean": rng.uniform(size=3).astype(np.float32),
                           "register.valid": rng.uniform(size=(4, 4)) > 0.5}  # fmt: skip


def _append_all(material, frames):
    appender = LiveAppender(material)
    rows: dict = {}
    for header, arrays in frames:
        for key, row in live_rows(header, arrays).items():
            rows.setdefault(key, []).append(row)
    for key, batch in rows.items():
        appender.append(*key, batch)


def test_live_round_trip_keeps_arrival_order_and_frame_ids():
    frames = list(_frames())
    material = group()
    _append_all(material, frames)
    live = read_live(material["live"])
    assert sorted(live) == ["register", "stats"] and sorted(live["stats"]) == ["cam0", "cam2"]
    got = live["stats"]["cam2"]
    assert got.step.tolist() == [3, 1, 2] and got.sub.tolist() == [0, 0, 0]
    by_step = {h["step"]: a["stats.mean"] for h, a in frames if h["camera"] == "cam2"}
    np.testing.assert_array_equal(got.arrays["mean"], np.stack([by_step[s] for s in (3, 1, 2)]))
    assert live["register"]["cam0"].arrays["valid"].shape == (3, 4, 4)
    live_group = material["live"]
    del live_group.attrs["format"], live_group.attrs["version"]  # before versioning: still reads
    assert read_live(live_group)["stats"]["cam0"].step.tolist() == [3, 1, 2]


def test_rows_beyond_step_are_not_read_and_are_cut_before_the_next_append():
    material = group()
    _append_all(material, list(_frames())[:2])
    torn = material["live"]["stats"]["cam0"]
    torn["mean"].append(np.ones((1, 3), np.float32))  # a batch a crash cut short: no step
    assert read_live(material["live"])["stats"]["cam0"].arrays["mean"].shape == (1, 3)
    _append_all(material, list(_frames())[2:4])
    again = read_live(material["live"])["stats"]["cam0"]
    assert again.step.tolist() == [3, 1] and again.arrays["mean"].shape == (2, 3)
    assert not np.any(again.arrays["mean"] == 1.0)


def test_bad_live_results_are_named():
    with pytest.raises(MaterialError, match=r"'mean': name it '<stage>\.<array>'"):
        live_rows({"step": 0, "sub": 0, "camera": "c"}, {"mean": np.zeros(1)})
    rows = [live_rows({"step": s, "sub": 0, "camera": "c"}, {"stats.mean": np.zeros(s + 1)})
            for s in range(2)]  # fmt: skip
    batch = [r[("stats", "c")] for r in rows]
    with pytest.raises(MaterialError, match=r"live/stats/c: mean has shapes \[\(1,\), \(2,\)\]"):
        LiveAppender(group()).append("stats", "c", batch)
    other = live_rows({"step": 1, "sub": 0, "camera": "c"}, {"stats.max": np.zeros(1)})
    with pytest.raises(MaterialError, match=r"step 1 sub 0 returned \['max'\]"):
        LiveAppender(group()).append("stats", "c", [batch[0], other[("stats", "c")]])


def test_flat_field_round_trip_replaces_and_reads_the_old_npz(tmp_path):
    falloff = np.random.default_rng(0).uniform(0.5, 1.0, (2, 6, 5)).astype(np.float32)
    path = tmp_path / "cal.flatfield.zarr"
    write_flat_field(path, FlatFieldMaps("cam2", ("near30", "sun45"), falloff))
    write_flat_field(path, FlatFieldMaps("cam2", ("near30", "sun45"), falloff * 2))  # replaced
    got = read_flat_field(path)
    assert got.camera == "cam2" and got.lamps == ("near30", "sun45")
    np.testing.assert_array_equal(got.falloff, falloff * 2)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cal.flatfield.zarr"]
    old = tmp_path / "cal.flatfield.npz"
    np.savez_compressed(old, camera="cam2", lamps=["near30", "sun45"], falloff=falloff)
    np.testing.assert_array_equal(read_flat_field(old).falloff, falloff)


def test_an_archive_keeps_its_copy_of_the_flat_fields(tmp_path):
    falloff = np.random.default_rng(1).uniform(0.5, 1.0, (2, 6, 5)).astype(np.float32)
    write_flat_field(tmp_path / "cal.flatfield.zarr", FlatFieldMaps("cam0", ("a", "b"), falloff))
    archive = tmp_path / "s.zarr"
    (archive / "calibration").mkdir(parents=True)
    copy = copy_flat_field(tmp_path / "cal.toml", "cal.flatfield.zarr", archive)
    assert copy == archive_flat_field_path(archive, "cal.flatfield.zarr")
    assert copy == archive / "calibration" / "cal.flatfield.zarr"
    np.testing.assert_array_equal(read_flat_field(copy).falloff, falloff)
    with pytest.raises(MaterialError, match=r"lamps_flat_field = '../x.zarr': .* not a path"):
        archive_flat_field_path(archive, "../x.zarr")
    with pytest.raises(MaterialError, match="no flat fields here"):
        copy_flat_field(tmp_path / "cal.toml", "other.flatfield.zarr", archive)


def test_bad_flat_fields_are_named(tmp_path):
    falloff = np.ones((2, 4, 4), np.float32)
    with pytest.raises(MaterialError, match=r"falloff has shape \(2, 4, 4\) for lamps \['a'\]"):
        write_flat_field(tmp_path / "f.zarr", FlatFieldMaps("cam0", ("a",), falloff))
    with pytest.raises(MaterialError, match="no flat fields here"):
        read_flat_field(tmp_path / "missing.zarr")
    path = write_flat_field(tmp_path / "f.zarr", FlatFieldMaps("cam0", ("a", "b"), falloff))
    g = zarr.open_group(path, mode="r+")
    g.attrs["version"] = 3
    with pytest.raises(MaterialError, match="flatfield group has version 3"):
        read_flat_field(path)
