"""The btf stage's hard cases, through ``rig process --stages btf`` on small sessions of the
simulated rig (16² texels): each stays finite, and the material says what happened."""

from __future__ import annotations

import re
import shutil
import tomllib
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from orchestrator.cli import app
from orchestrator.local import run_local
from processing.btf import BtfError, interpolate, reconstruct
from processing.offline.texel_light import IRRADIANCE_FLOOR
from rig.archive import Archive
from rig.calfile import CalibrationFile, CameraResult, LampResult
from rig.clock import VirtualClock
from rig.config import RigConfig
from rig.kinematics import lamp_position_mm
from rig.material import (
    FlatFieldMaps,
    archive_flat_field_path,
    btf_from_arrays,
    read_material,
    write_flat_field,
)
from sim.rig import SimulatedRig
from sim.scene import scene_from_dict

SIZE = 16
VIEWS = "[[0, 0], [30, 0], [30, 90]]"
#: the plan's one light, lit by lamp3 (θ = 45°) with the arc at 0°
LAMP = "lamp3"


def _record(folder: Path, views: str, lights: str, exposure_s: float = 0.05) -> Path:
    data = tomllib.loads(Path("examples/scenes/bumps.toml").read_text())
    data["render"] = {"scale": 0.25, "supersample": 1}  # 256 × 192 px frames
    plan = folder / "plan.toml"
    plan.write_text(f'[sample]\nname = "hard"\n[captures.btf]\nviews = {views}\n'
                    f"lights = {lights}\n[exposure]\nexposure_s = {exposure_s}\n")  # fmt: skip
    clock = VirtualClock()
    with SimulatedRig(scene_from_dict(data), clock=clock) as sim:
        final = run_local(plan, sim.rig_config(), archive=folder / "s.zarr", clock=clock)
    assert final["state"] == "done", final
    return folder / "s.zarr"


@pytest.fixture(scope="module")
def one_light(tmp_path_factory):
    """Three view slots, one light each."""
    return _record(tmp_path_factory.mktemp("one_light"), VIEWS, "[[45, 0]]")


@pytest.fixture
def session(one_light, tmp_path):
    """A copy of ``one_light`` to give a calibration."""
    return Path(shutil.copytree(one_light, tmp_path / "s.zarr"))


def _process(archive: Path, *options: str) -> tuple[np.ndarray, dict]:
    """``rig process ARCHIVE --stages btf``; every light's normtexture of every slot
    (slots, lights, N, N, C) and the material's record of corrections."""
    args = ["process", str(archive), "--stages", "btf", "--size", str(SIZE), "--workers", "1"]
    result = CliRunner().invoke(app, [*args, *options])
    assert result.exit_code == 0, result.output
    with Archive.open(archive) as arch:
        group = arch.material["btf"]
        arrays, attrs = {k: group[k][:] for k in group.array_keys()}, dict(group.attrs)
    assert arrays["slot_valid"].all()
    model = btf_from_arrays(arrays, attrs)
    values = np.stack([
        np.stack([reconstruct(model, view=v, light=x) for x in range(len(model.light_dirs_deg))])
        for v in range(len(model.view_dirs_deg))
    ])  # fmt: skip
    assert np.isfinite(values).all()
    return values, attrs["radiometry"]


def _calibrate(archive: Path, calibration: CalibrationFile) -> None:
    with Archive.open(archive, mode="a") as arch:
        arch.set_calibration(calibration.model_dump(mode="json", exclude_none=True))


def _lamp_mm(**moved) -> tuple[float, float, float]:
    """lamp3's position with the arc at 0°, with coordinates replaced."""
    position = lamp_position_mm(RigConfig(), LAMP, arc_deg=0.0, turntable_deg=0.0)
    axes = {"x": 0, "y": 1, "z": 2}
    for axis, value in moved.items():
        position[axes[axis]] = value
    return tuple(float(v) for v in position)


def test_a_plan_with_one_light_compresses_interpolates_and_resamples(one_light, tmp_path):
    values, record = _process(one_light, "--components", "1")
    assert record["sources"]["irradiance"] == "the rig config's lamp geometry (nominal)"
    assert record["skipped"]["all"] == "the archive holds no calibration"
    assert values.shape == (3, 1, SIZE, SIZE, 3) and values.max() > 0
    with Archive.open(one_light) as arch:
        group = arch.material["btf"]
        model = btf_from_arrays({k: group[k][:] for k in group.array_keys()}, dict(group.attrs))
    # one light: every light direction is that light's, the views blend
    held_out = interpolate(model, view_deg=(20.0, 45.0), light_deg=(60.0, 200.0))
    assert np.isfinite(held_out).all() and held_out.max() > 0
    with pytest.raises(BtfError, match="needs ≥ 3 measured directions"):
        interpolate(model, view_deg=(0.0, 0.0), light_deg=(45.0, 0.0), light_method="barycentric")
    # more components than lights, and per-texel views resample the slots
    copy = Path(shutil.copytree(one_light, tmp_path / "c8.zarr"))
    resampled, record = _process(copy, "--components", "8", "--views", "per-texel")
    outside = re.match(r"(\d+) of (\d+) texel views outside the hull", record["skipped"]["view"])
    assert outside is not None, record["skipped"]["view"]
    assert 0 < int(outside[1]) < int(outside[2]) == 3 * SIZE * SIZE
    assert record["sources"]["view"] == "the rig config's camera geometry (nominal)"
    # nothing invented: a texel outside its hull keeps its value (one light: the slot's mean,
    # float16 as stored); those inside it moved
    kept = (resampled == values).all(axis=-1)
    assert int(outside[1]) <= kept.sum() < kept.size


def test_directions_moved_by_the_model_need_its_fit_and_say_so(session):
    """--lights/--views model scale each texel capture by the fitted PBR model's change
    between its own directions and the nominal ones: without a fit (or one at another
    size) nothing moves and the record says why; with one, every value moves by a few %
    at most, nowhere a NaN."""
    measured, record = _process(session, "--lights", "model")
    assert record["skipped"]["model"] == (
        "no fitted PBR model in the material: run the pbr stage first: every slot kept at "
        "the texels' own directions"
    )
    assert "model" not in record["sources"]
    result = CliRunner().invoke(app, ["process", str(session), "--stages", "pbr", "--workers",
                                      "1"])  # fmt: skip
    assert result.exit_code == 0, result.output
    moved, record = _process(session, "--lights", "model", "--views", "model")
    assert record["sources"]["model"].startswith("lights and views moved by the fitted PBR model")
    assert np.isfinite(moved).all()
    change = np.abs(moved - measured) / measured.max()
    assert 1e-4 < change.max() < 0.1  # a lamp 650 mm and a camera 800 mm away: a few %
    # a fit on another grid is not used
    args = ["--stages", "btf", "--size", str(2 * SIZE), "--lights", "model", "--workers", "1"]
    result = CliRunner().invoke(app, ["process", str(session), *args])
    assert result.exit_code == 0, result.output
    with Archive.open(session) as arch:
        why = dict(arch.material["btf"].attrs)["radiometry"]["skipped"]["model"]
    assert why.startswith(f"the fitted PBR model is {SIZE}² texels, the stage's grid {2 * SIZE}²")
    # the model fitted in the same command would come after the move: refused, nothing run
    args = ["--stages", "btf,pbr", "--views", "model"]
    result = CliRunner().invoke(app, ["process", str(session), *args])
    assert result.exit_code == 2
    assert "--views model moves the BTF by the fitted PBR model" in result.output
    assert "run --stages btf,pbr first, then --stages btf --views model" in result.output


def test_a_plan_with_one_view_keeps_its_views_and_says_why(tmp_path):
    archive = _record(tmp_path, "[[30, 0]]", "[[45, 0], [30, 120], [60, 240]]")
    values, record = _process(archive, "--components", "8", "--views", "per-texel")
    assert values.shape == (1, 3, SIZE, SIZE, 3)
    assert record["skipped"]["view"].startswith("1 view slot(s) with data: no hull of views")
    assert "view" not in record["sources"]


@pytest.mark.parametrize("z_mm", [0.5, 0.0, -3.0])
def test_a_lamp_at_grazing_stays_finite_and_what_it_barely_lights_is_counted(session, z_mm):
    """lamp3 calibrated at (or below) the height of the sample's plane: its irradiance at
    the centre is ~0 (or none), so each texel's would be a ratio of ~0s."""
    raw, _ = _process(session, "--components", "1", "--raw")  # no irradiance divided out
    _calibrate(session, CalibrationFile(lamps={LAMP: LampResult(position_mm=_lamp_mm(z=z_mm))}))
    values, record = _process(session, "--components", "1")
    assert record["sources"]["irradiance"].startswith("calibrated lamp positions")
    flagged = record["skipped"].get(f"irradiance {LAMP}")
    if z_mm > 0:  # low, but above every texel's horizon: a ratio of small numbers, no floor
        assert flagged is None
        # in the plane of the sample, 650 mm away ± up to the half-diagonal d: each texel's
        # irradiance is (650 / (650 ± d))³ of the centre's
        d, ratio = 50.0 * np.sqrt(2.0), raw / np.maximum(values, 1e-6)
        lit = raw > 0.05 * raw.max()
        assert ratio[lit].min() > (650.0 / (650.0 + d)) ** 3 - 0.01
        assert ratio[lit].max() < (650.0 / (650.0 - d)) ** 3 + 0.01
        assert ratio[lit].max() - ratio[lit].min() > 0.5  # divided out, not left
    else:  # it lights no texel: each divided by the floor, all of them counted
        assert flagged is not None and flagged.startswith(f"{3 * SIZE * SIZE} texel captures")
        assert "at or below the sample's plane" in flagged
        np.testing.assert_allclose(values, raw / IRRADIANCE_FLOOR, rtol=0.01, atol=1e-3)


def test_texels_a_lamps_flat_field_barely_lights_are_counted(session):
    """lamp3's flat field (as a lamp near grazing gives: light on one side of the white
    target only) at 1 % of the centre's over half of it: those texels are divided by the
    floor, not by ~0, and counted."""
    camera = RigConfig().camera("cam0")  # overhead: the map spans the sample
    falloff = np.ones((1, camera.height // 8, camera.width // 8), np.float32)
    falloff[:, :, falloff.shape[2] // 2 :] = 0.01
    write_flat_field(archive_flat_field_path(session, "ff.zarr"),
                     FlatFieldMaps("cam0", (LAMP,), falloff))  # fmt: skip
    _calibrate(session, CalibrationFile(lamps_flat_field="ff.zarr"))
    _, record = _process(session, "--components", "1")
    assert LAMP in record["flat_fielded"]
    dim = record["skipped"][f"flat field {LAMP}"]
    count = int(dim.split()[0])
    assert 0.25 * 3 * SIZE * SIZE < count < 0.75 * 3 * SIZE * SIZE, dim


def _camera(camera_id: str) -> dict[str, CameraResult]:
    cam = RigConfig().camera_model("cam0")
    moved = (cam.t + np.array([8.0, 0.0, 0.0])).tolist()
    result = CameraResult(K=cam.K.tolist(), dist=(0.0,) * 5, R=cam.R.tolist(), t=moved,
                          image_size=(cam.width, cam.height), rms_px=0.1, images=12)  # fmt: skip
    return {camera_id: result}


MOVED = LampResult(position_mm=_lamp_mm(z=300.0))  # far from where lamp3 stands
#: case → (calibration, the record's key that says why it is not used, what it names)
ANOTHER_RIG = {
    "another rig's name": (
        CalibrationFile(rig="bench-2", lamps={LAMP: MOVED}, cameras=_camera("cam0")),
        "all",
        "bench-2",
    ),
    "other lamp ids": (CalibrationFile(lamps={"lampX": MOVED}), "lamps", "lampX"),
    "more lamps than the rig's": (
        CalibrationFile(lamps={f"lamp{i}": MOVED for i in range(10)}),
        "lamps",
        "lamp8, lamp9",
    ),
    "other camera ids": (CalibrationFile(cameras=_camera("camX")), "cameras", "camX"),
}


@pytest.mark.parametrize("case", ANOTHER_RIG, ids=list(ANOTHER_RIG))
def test_another_rigs_calibration_is_skipped_with_the_reason(session, case):
    calibration, key, named = ANOTHER_RIG[case]
    nominal, _ = _process(session, "--components", "1", "--views", "per-texel")
    _calibrate(session, calibration)
    values, record = _process(session, "--components", "1", "--views", "per-texel")
    assert named in record["skipped"][key]
    assert record["sources"]["irradiance"] == "the rig config's lamp geometry (nominal)"
    assert record["sources"]["view"] == "the rig config's camera geometry (nominal)"
    np.testing.assert_array_equal(values, nominal)  # processed with the nominal values
    corrections = read_material(session).provenance["corrections"]  # it says the same
    assert "camX" not in corrections["cameras"]
    assert corrections["cameras"] == []  # the one camera named is another rig's, or none


def test_the_rigs_own_calibration_is_used(session):
    """The counterpart of the cases above: the same moved lamp, this rig's, changes values."""
    nominal, _ = _process(session, "--components", "1")
    _calibrate(session, CalibrationFile(rig="default", lamps={LAMP: MOVED}))
    values, record = _process(session, "--components", "1")
    assert record["sources"]["irradiance"].startswith("calibrated lamp positions")
    assert not {"all", "lamps"} & set(record["skipped"])
    assert np.abs(values - nominal).max() > 0.01 * nominal.max()


def test_saturated_texels_are_stored_as_clipped_and_counted(tmp_path):
    # 1.6 × the exposure: the brightest pixels (164 of 255 at 0.05 s) clip, a few texels' worth
    archive = _record(tmp_path, VIEWS, "[[45, 0], [30, 120]]", exposure_s=0.08)
    _, record = _process(archive, "--components", "2")
    count = int(record["skipped"]["saturated"].split()[0])
    assert 0 < count < 3 * 2 * SIZE * SIZE // 2  # the texel captures over them, every slot's
