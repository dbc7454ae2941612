"""Per-texel view directions: each texel's own view, resampled onto the plan's views."""

from __future__ import annotations

import numpy as np
import pytest

from processing.btf import CompressedBTF, compress_view
from processing.offline.texel_resample import texel_directions, texel_resampling
from processing.offline.texel_view import SlotCamera, per_texel_views
from rig.config import RigConfig
from rig.geometry import direction_vector
from rig.material import Radiometry

SIZE = 16
SAMPLE_MM = 100.0
#: The coarse plan's views: the zenith and a ring at 45°, plus a 60° ring
NOMINAL = np.array([[0, 0], *[[45, p] for p in (0, 90, 180, 270)],
                    *[[60, p] for p in (45, 135, 225, 315)]], float)  # fmt: skip


def _centres(distance_mm: float) -> list[np.ndarray]:
    """Camera centres at ``distance_mm`` from the turntable centre along each nominal view."""
    return [distance_mm * direction_vector(t, p) for t, p in NOMINAL]


def _own(distance_mm: float) -> np.ndarray:
    return np.stack([texel_directions(c, SAMPLE_MM, SIZE) for c in _centres(distance_mm)])


def test_a_texel_sees_the_camera_from_where_it_lies():
    camera = np.array([0.0, -565.7, 565.7])  # 800 mm away at 45°
    v = texel_directions(camera, SAMPLE_MM, SIZE)
    np.testing.assert_allclose(np.linalg.norm(v, axis=-1), 1.0)
    # row 0 lies at +y, away from the camera: it sees the camera lower (larger θ)
    theta = np.degrees(np.arccos(v[..., 2]))
    assert theta[0].mean() > 45.0 > theta[-1].mean()
    assert 4.0 < theta[0].mean() - theta[-1].mean() < 6.0  # ±2.4° across the rows


def test_a_telecentric_camera_needs_no_resampling():
    plan = texel_resampling(NOMINAL, _own(1e9))
    assert plan.turn_deg.max() < 1e-4  # on the outer ring half the texels fall just outside
    own_weight = np.where(plan.indices == np.arange(len(NOMINAL))[:, None, None, None],
                          plan.weights, 0.0).sum(-1)  # fmt: skip
    np.testing.assert_allclose(own_weight, 1.0, atol=1e-6)


def test_the_blend_moves_a_smooth_view_dependence_towards_the_nominal_view():
    """f(v) = cos θ on the 60° ring, where each texel's own views surround the nominal
    one closely: the blend lands nearer f(nominal) than the texel's own measurement.
    Nothing is invented outside the texel's hull: its own value, weight 1."""
    own = _own(800.0)
    plan = texel_resampling(NOMINAL, own)
    f = own[..., 2]  # (S, n, n)
    want = np.cos(np.radians(NOMINAL[:, 0]))[:, None, None]
    rows, cols = np.indices((SIZE, SIZE))
    blended = (plan.weights * f[plan.indices, rows[..., None], cols[..., None]]).sum(-1)
    np.testing.assert_allclose(plan.weights.sum(-1), 1.0)
    assert (plan.weights >= 0).all()
    ring = (NOMINAL[:, 0] == 60)[:, None, None] & ~plan.outside
    assert ring.any()
    assert np.abs(blended - want)[ring].mean() < 0.5 * np.abs(f - want)[ring].mean()
    np.testing.assert_array_equal(blended[plan.outside], f[plan.outside])
    assert 0.2 < plan.outside.mean() < 0.8 and plan.turn_deg.max() < 6.0


def _model(lights: int, slots: int = len(NOMINAL)) -> CompressedBTF:
    rng = np.random.default_rng(0)
    views = [compress_view(rng.uniform(0.1, 1.0, (lights, SIZE, SIZE, 3)).astype(np.float32),
                           components=lights) for _ in range(slots)]  # fmt: skip
    return CompressedBTF(
        NOMINAL[:slots], np.array([[45.0, 30.0 * i] for i in range(lights)]),
        np.stack([v.mean for v in views]), np.stack([v.basis for v in views]),
        np.stack([v.weights for v in views]), np.stack([v.singular_values for v in views]),
        np.array([v.rank for v in views], np.int32),
    )  # fmt: skip


def _cameras(distance_mm=800.0, source="the rig config's camera geometry (nominal)"):
    return [SlotCamera(c, source) for c in _centres(distance_mm)]


@pytest.mark.parametrize("lights", [1, 5])  # a plan with one light too
def test_the_material_records_the_views_and_the_texels_outside_the_hull(lights):
    model = _model(lights)
    valid = np.ones(len(NOMINAL), bool)
    out, record = per_texel_views(model, _cameras(), valid, Radiometry(), sample_mm=SAMPLE_MM,
                                  components=lights)  # fmt: skip
    assert record.sources["view"] == "the rig config's camera geometry (nominal)"
    assert "outside the hull" in record.skipped["view"]
    for array in (out.mean, out.basis, out.weights):
        assert np.isfinite(np.asarray(array, np.float64)).all()
    assert not np.array_equal(out.mean, model.mean)  # the texels moved


def test_unplaced_cameras_or_too_few_views_are_skipped_with_the_reason():
    model = _model(3)
    valid = np.ones(len(NOMINAL), bool)
    cameras = _cameras()
    cameras[2] = SlotCamera(None, "imported normtextures: no camera to place")
    out, record = per_texel_views(model, cameras, valid, Radiometry(), sample_mm=SAMPLE_MM,
                                  components=3)  # fmt: skip
    assert out is model and "view" not in record.sources
    assert record.skipped["view"].startswith("imported normtextures")
    few = valid & (np.arange(len(NOMINAL)) < 2)
    out, record = per_texel_views(model, _cameras(), few, Radiometry(), sample_mm=SAMPLE_MM,
                                  components=3)  # fmt: skip
    assert out is model and "2 view slot(s) with data" in record.skipped["view"]


def test_a_calibrated_camera_names_its_session(tmp_path):
    model = _model(2)
    source = "calibrated cameras, cal.zarr (2026-11-27T09:00:00)"
    _, record = per_texel_views(model, _cameras(source=source), np.ones(len(NOMINAL), bool),
                                Radiometry(), sample_mm=SAMPLE_MM, components=2)  # fmt: skip
    assert record.sources["view"] == source
    assert RigConfig().camera_arc.radius_mm == 800.0  # the distance these tests assume


def _archive(calibration, actuators=None):
    """What ``slot_camera`` reads of an archive of the default rig: one BTF step of cam3
    (at turntable 60° unless ``actuators`` says otherwise)."""
    from types import SimpleNamespace

    from rig.archive import StepRecord

    step = StepRecord(4, "btf", ("cam3",), {"cam3": (45.0, 300.0)}, (15.0, 0.0),
                      actuators or {"turntable_deg": 60.0})  # fmt: skip
    dumped = None if calibration is None else calibration.model_dump(mode="json")
    return SimpleNamespace(plan={}, step_table=lambda: [step], calibration=dumped,
                           path="session.zarr", calibration_version=1,
                           rig_config={})  # fmt: skip


def _calibrated(camera_id: str, config: RigConfig, shift_mm: float):
    from rig.calfile import CalibrationFile, CameraResult

    cam = config.camera_model("cam3")
    result = CameraResult(K=cam.K.tolist(), dist=(0.0,) * 5, R=cam.R.tolist(),
                          t=(cam.t + np.array([shift_mm, 0.0, 0.0])).tolist(),
                          image_size=(cam.width, cam.height), rms_px=0.1, images=12)  # fmt: skip
    return CalibrationFile(cameras={camera_id: result})


def test_a_slot_camera_is_calibrated_where_the_calibration_has_it_else_nominal():
    from types import SimpleNamespace

    from processing.offline.texel_view import slot_camera

    config = RigConfig()
    slot = SimpleNamespace(captures=((4, "cam3"),))
    nominal = config.camera_model("cam3", turntable_deg=60.0).center
    missing = slot_camera(_archive(None), config, slot)
    assert missing.source == "the rig config's camera geometry (nominal)"
    np.testing.assert_allclose(missing.centre_mm, nominal, atol=1e-9)
    elsewhere = slot_camera(_archive(_calibrated("camX", config, 5.0)), config, slot)
    assert elsewhere.source == "the rig config's camera geometry (nominal)"
    calibrated = slot_camera(_archive(_calibrated("cam3", config, 5.0)), config, slot)
    assert calibrated.source.startswith("calibrated cameras, ")
    assert 4.0 < np.linalg.norm(calibrated.centre_mm - nominal) < 6.0
    arm_and_rail = {"tool_rx_deg": 0.0, "tool_ry_deg": 0.0, "tool_rz_deg": 0.0, "rail_deg": 90.0}
    on_the_rail = SimpleNamespace(captures=((4, "cam0"),))
    bonn = slot_camera(_archive(None, arm_and_rail), RigConfig(kind="bonn", bonn={}), on_the_rail)
    assert bonn.centre_mm is None and "anew at every step" in bonn.source
