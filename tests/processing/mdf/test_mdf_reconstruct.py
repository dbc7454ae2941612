"""End to end on analytic scans: accuracy, coverage and the hard cases.

Ground truth comes from ray marching the analytic height field
(``processing.mdf.synthetic``), independent of the reconstruction.
"""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from processing.mdf import (
    LaserLine,
    LineReason,
    MdfError,
    MdfSettings,
    Reason,
    ReferenceRegion,
    SpaceTimeTracker,
    displacement_image,
    merge_scans,
    reconstruct_scan,
    reference_footprint_mm,
    scan_planes,
)
from processing.mdf.synthetic import (
    RibbedSample,
    SyntheticScan,
    first_hit,
    render_scan,
    rig_scan,
    true_distance,
    visible_from,
)
from tests.budgets import scaled
from tests.processing.mdf.mdf_scenes import (
    ARCS,
    CONFIG,
    SAMPLE,
    SHEET_SIGMA_MM,
    camera,
    displacement,
    frames,
    grid,
    region,
    scan,
)


def truth(camera_id="cam2", sample=SAMPLE):
    cam = camera(camera_id)
    return true_distance(cam, sample, grid()), reference_footprint_mm(cam, grid())


def texel_points(cam, sample=SAMPLE):
    """First surface hit of every texel's view ray (independent ray march)."""
    q = np.column_stack([grid().reshape(-1, 2), np.zeros(grid()[..., 0].size)])
    d = q - cam.center
    points, hit = first_hit(cam.center, d / np.linalg.norm(d, axis=1)[:, None], sample)
    assert hit.all()
    return points


def swept(points, sc, margin=4):
    """Points the sweep crosses with a few frames to spare at both ends."""
    signed = points @ sc.normal.T - sc.offset  # (n, F)
    crossing = np.argmin(np.abs(signed), axis=1)
    return (crossing >= margin) & (crossing <= len(sc.offset) - 1 - margin)


def check_consistent(result):
    assert result.distance.dtype == np.float32 and result.reason.dtype == np.uint8
    assert np.all(np.isfinite(result.distance))
    valid = result.reason <= Reason.EDGE
    assert np.all(result.distance[valid] >= 0)
    assert np.all(result.distance[~valid] == -1)


def test_several_locations_meet_the_accuracy_and_coverage_goal():
    true_d, footprint = truth()
    merged = merge_scans([displacement(arc) for arc in ARCS])
    check_consistent(merged)
    seen = merged.distance >= 0
    error_px = np.abs(merged.distance - true_d)[seen] / footprint[seen]
    assert np.median(error_px) <= 0.1
    assert np.percentile(error_px, 95) <= 0.5
    # Coverage of the texels some location truly lit within its sweep.
    points = texel_points(camera())
    lit = np.zeros(len(points), bool)
    for arc in ARCS:
        lit |= visible_from(points, scan(arc).source_mm, SAMPLE) & swept(points, scan(arc))
    lit = lit.reshape(seen.shape)
    assert lit.mean() > 0.99
    assert seen[lit].mean() >= 0.99
    assert np.all(merged.count[seen] >= 1)


def test_each_location_alone_is_accurate_where_it_has_a_value():
    true_d, footprint = truth()
    for arc in ARCS:
        d = displacement(arc)
        check_consistent(d)
        v = d.distance >= 0
        assert v.mean() > 0.9
        assert np.median(np.abs(d.distance - true_d)[v] / footprint[v]) < 0.1
        assert d.weight > 0


@pytest.mark.parametrize("method", ["centroid", "blais_rioux"])
def test_other_peak_detectors_work_end_to_end(method):
    true_d, footprint = truth()
    d = displacement(162.0, method=method)
    v = d.distance >= 0
    assert v.mean() > 0.9
    assert np.median(np.abs(d.distance - true_d)[v] / footprint[v]) < 0.25


def test_shadowed_texels_are_unseen_not_guessed():
    deep = RibbedSample(base_mm=-9.0, bumps=())
    cam, reg, sc = camera(), region(), scan(162.0)
    result = reconstruct_scan(
        render_scan(cam, deep, sc, sheet_sigma_mm=SHEET_SIGMA_MM),
        reg,
        grid(),
        source_mm=sc.source_mm,
        sheet_angle_deg=sc.angle_deg,
    )
    check_consistent(result)
    points = texel_points(cam, deep)
    lit = (visible_from(points, sc.source_mm, deep) & swept(points, sc)).reshape(32, 32)
    # Texels whose whole 3×3 neighbourhood agrees (no half-lit edge pixels).
    pad = np.pad(lit, 1, mode="edge")
    all_dark = ~np.any([pad[i : i + 32, j : j + 32] for i in range(3) for j in range(3)], axis=0)
    all_lit = np.all([pad[i : i + 32, j : j + 32] for i in range(3) for j in range(3)], axis=0)
    assert all_dark.sum() > 20  # the recess wall casts a real shadow
    assert np.all(result.distance[all_dark] == -1)
    # Unlit pixels, or (at the sweep's far end) a peak on the last frames.
    assert np.isin(result.reason[all_dark], [Reason.UNLIT, Reason.AT_SEQUENCE_EDGE]).all()
    assert np.mean(result.reason[all_dark] == Reason.UNLIT) > 0.9
    assert (result.distance[all_lit] >= 0).mean() > 0.98
    true_d, footprint = truth(sample=deep)
    v = result.distance >= 0
    assert np.median(np.abs(result.distance - true_d)[v] / footprint[v]) < 0.1


def test_grazing_planes_are_flagged():
    # cam3 (θ = 45°) and the laser at arc 0 (θ = 45° on the same side): the
    # laser sheets nearly contain the view rays.
    cam = camera("cam3")
    sc = rig_scan(CONFIG, arc_deg=0.0, step_deg=0.12, sweep_deg=11.0)
    reg = region("cam3")
    result = reconstruct_scan(
        render_scan(cam, SAMPLE, sc, sheet_sigma_mm=SHEET_SIGMA_MM),
        reg,
        grid(),
        source_mm=sc.source_mm,
        sheet_angle_deg=sc.angle_deg,
    )
    check_consistent(result)
    counts = np.bincount(result.reason.ravel(), minlength=len(Reason))
    assert counts[Reason.GRAZING] > 0.5 * result.reason.size
    true_d, footprint = truth("cam3")
    v = result.distance >= 0
    # What survives the guard is no wild value.
    assert np.all(np.abs(result.distance - true_d)[v] / footprint[v] < 10)
    # Without the guard the same scan yields huge displacements.
    loose = reconstruct_scan(
        render_scan(cam, SAMPLE, sc, sheet_sigma_mm=SHEET_SIGMA_MM),
        reg,
        grid(),
        source_mm=sc.source_mm,
        sheet_angle_deg=sc.angle_deg,
        settings=MdfSettings(max_error_gain=1e9, above_tol_px=1e9, edge_tol_px=1e9),
    )
    lv = loose.distance >= 0
    assert np.max(np.abs(loose.distance - true_d)[lv] / footprint[lv]) > 10


def test_frames_without_a_line_give_no_plane():
    arc = 162.0
    sc, reg = scan(arc), region()
    broken = [f.copy() for f in frames(arc)]
    for i in range(40, 46):
        broken[i][reg.mask] = 8  # the strip vanished from the plate
    result = reconstruct_scan(
        broken, reg, grid(), source_mm=sc.source_mm, sheet_angle_deg=sc.angle_deg
    )
    check_consistent(result)
    assert np.sum(result.reason == Reason.NO_PLANE) > 10
    true_d, footprint = truth()
    v = result.distance >= 0
    assert np.max(np.abs(result.distance - true_d)[v] / footprint[v]) < 1.0


def test_seed_constant_angle_model_on_parallel_planes():
    # Parallel sheets at 50° to the plate (an emitter far away), as the seed assumes.
    angle = np.deg2rad(50.0)
    m = np.array([np.cos(0.3), np.sin(0.3)])
    normal = np.array([-np.sin(angle) * m[0], -np.sin(angle) * m[1], np.cos(angle)])
    rho = np.arange(-75.0, 75.0, 1.6)
    far = 1e5 * np.array([np.cos(angle) * m[0], np.cos(angle) * m[1], np.sin(angle)])
    sc = SyntheticScan(
        normal=np.tile(normal, (len(rho), 1)),
        offset=-np.sin(angle) * rho,
        source_mm=far,
        angle_deg=np.full(len(rho), 50.0),
    )
    cam, reg = camera(), region()
    result = reconstruct_scan(
        render_scan(cam, SAMPLE, sc, sheet_sigma_mm=SHEET_SIGMA_MM),
        reg,
        grid(),
        source_mm=far,
        sheet_angle_deg=50.0,
    )
    true_d, footprint = truth()
    v = result.distance >= 0
    assert v.mean() > 0.95
    assert np.median(np.abs(result.distance - true_d)[v] / footprint[v]) < 0.1


def test_frame_count_mismatch_is_an_error():
    tracker = SpaceTimeTracker(region().mask.shape, min_contrast=20.0)
    for f in frames(162.0)[:5]:
        tracker.update(f)
    lines = [LaserLine(np.zeros(2), 0.0, 0, 0, 0.0, 0.0, LineReason.NO_CANDIDATES)] * 4
    planes = scan_planes(lines, source_mm=scan(162.0).source_mm)
    with pytest.raises(MdfError, match="4 planes for a scan of 5 frames"):
        displacement_image(tracker.result(), planes, camera(), grid(), weight=1.0)
    with pytest.raises(MdfError, match="texels_xy"):
        displacement_image(tracker.result(), planes, camera(), grid()[0], weight=1.0)


@scaled(0.15)
@given(
    theta=st.sampled_from(["cam0", "cam1", "cam4", "cam5"]),
    arc=st.floats(0, 360),
    step=st.floats(0.1, 0.4),
    noise=st.floats(0, 20),
)
def test_any_scan_is_finite_and_consistent(theta, arc, step, noise):
    cam = CONFIG.camera_model(theta).scaled(0.0625)
    reg = ReferenceRegion.from_holder(cam, sample_mm=100.0, plate_mm=180.0)
    sc = rig_scan(CONFIG, arc_deg=arc, step_deg=step, sweep_deg=11.0)
    result = reconstruct_scan(
        render_scan(cam, SAMPLE, sc, sheet_sigma_mm=3.0, noise_sigma=noise),
        reg,
        grid(),
        source_mm=sc.source_mm,
        sheet_angle_deg=sc.angle_deg,
    )
    check_consistent(result)
    assert np.isfinite(result.weight) and result.weight >= 0
