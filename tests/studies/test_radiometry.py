"""Radiometric corrections in processing, on sessions recorded against the simulated rig.

A bumps sample seen through a gamma-2.2 camera (``response``) with ``vignetting``,
lit by the rig's near lamps; the response curves (Debevec & Malik from wedge
brackets) and the flat fields (white target) come from calibration sessions of the
same simulated rig, and the daemon copies them into the sample's archive
(``studies.radiometry``, ``rig bench radiometry``). Margins: with the
corrections the PS mean angular error is under half of the raw one, the albedo
contrast of the checker's two materials within 1 % of the truth (raw: > 10 % off,
gamma compresses it), the BTF's relative RMSE under 60 % of the raw one.
"""

from __future__ import annotations

import numpy as np
import pytest
from typer.testing import CliRunner

from orchestrator.cli import app
from processing.offline.radiometry import frame_corrections
from rig.archive import Archive, FrameFormat
from rig.config import RigConfig, default_rig_config
from rig.material import archive_flat_field_path, read_material
from studies.radiometry import QUICK, measure, record

# Sessions, subprocesses or benches: the full tier only (make test), not make quick.
pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def archive(tmp_path_factory):
    return record(tmp_path_factory.mktemp("radiometry"), **QUICK)


def test_corrections_bring_ps_and_btf_close_to_the_truth(archive):
    raw = measure(archive, raw=True, **QUICK)
    corrected = measure(archive, raw=False, **QUICK)
    assert raw["corrections"] == "none"
    assert corrected["corrections"] == "response + flat field (1 lamps)"
    assert corrected["btf_slots"] == raw["btf_slots"] == 2
    assert corrected["ps_mean_deg"] < 0.5 * raw["ps_mean_deg"], (raw, corrected)
    assert abs(corrected["albedo_contrast_err"]) < 0.01 < 0.1 < abs(raw["albedo_contrast_err"])
    assert corrected["btf_rel_rmse"] < 0.6 * raw["btf_rel_rmse"], (raw, corrected)
    assert all(np.isfinite(v) for v in corrected.values() if isinstance(v, float))


def test_the_material_records_what_was_applied_and_raw_switches_it_off(archive):
    runner = CliRunner()
    result = runner.invoke(
        app, ["process", str(archive), "--stages", "ps", "--size", "16", "--raw"]
    )
    assert result.exit_code == 0, result.output
    (view,) = read_material(archive).ps.values()
    assert not view.radiometry.applied
    assert "--raw" in view.radiometry.skipped["all"]
    result = runner.invoke(app, ["process", str(archive), "--stages", "ps", "--size", "16"])
    assert result.exit_code == 0, result.output
    (view,) = read_material(archive).ps.values()
    record = view.radiometry
    assert record.linearised == ("cam0",) and record.flat_fielded == ("lamp3",)
    assert record.calibration_version == 1
    assert (
        "response-" in record.sources["response"] and "white.zarr" in record.sources["flat_field"]
    )
    # the daemon copied the flat fields the rig config's calibration names
    with Archive.open(archive) as recorded:
        name = recorded.calibration["lamps_flat_field"]
    assert (archive_flat_field_path(archive, name) / "zarr.json").is_file()


def test_a_deeper_camera_keeps_its_frames_and_says_why(tmp_path):
    rig = default_rig_config().model_dump(mode="json")
    rig["camera_arc"]["cameras"][0]["bit_depth"] = 12
    curve = [[float(v / 128)] * 3 for v in range(256)]
    calibration = {"format_version": 1, "response": {"cam0": {"curve": curve, "exposures": 6}}}
    cameras = {"cam0": FrameFormat(4, 4, 3, "uint16")}
    with Archive.create(
        tmp_path / "a.zarr", plan={}, rig_config=rig, cameras=cameras, calibration=calibration
    ) as archive:
        corrections = frame_corrections(archive, RigConfig.model_validate(rig))
    assert not corrections.curves
    record = corrections.record(cameras=["cam0"], lamps=[])
    assert record.linearised == () and "12-bit frames" in record.skipped["cam0"]


def test_missing_flat_fields_and_curves_are_named(tmp_path):
    config = default_rig_config()
    calibration = {"format_version": 1, "lamps_flat_field": "cal.flatfield.zarr"}
    cameras = {"cam0": FrameFormat(4, 4, 3, "uint8")}
    rig = config.model_dump(mode="json")
    with Archive.create(
        tmp_path / "a.zarr", plan={}, rig_config=rig, cameras=cameras, calibration=calibration
    ) as archive:
        corrections = frame_corrections(archive, RigConfig.model_validate(archive.rig_config))
    assert corrections.flat_field is None and not corrections.curves
    assert "rig calibrate lamps --apply" in corrections.skipped["flat_field"]
    assert "no response curve" in corrections.skipped["response"]
    record = corrections.record(cameras=["cam0"], lamps=["lamp0"])
    assert not record.applied and set(record.skipped) == {"flat_field", "response"}
