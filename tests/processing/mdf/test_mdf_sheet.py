"""Laser planes from lines (seed's angle model and the emitter pencil), interpolation,
tetrahedron weights."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from processing.mdf import (
    LaserLine,
    LineReason,
    MdfError,
    scan_planes,
    sheet_from_line,
    tetrahedron_weight,
)
from processing.mdf.synthetic import rig_scan
from tests.processing.mdf.mdf_scenes import CONFIG


def exact_line(normal, offset):
    """The true strip of plane (normal, offset) on z = 0 as a LaserLine."""
    m = normal[:2] / np.linalg.norm(normal[:2])
    return LaserLine(m, offset / np.linalg.norm(normal[:2]), 50, 50, 0.0, 100.0, LineReason.OK)


@pytest.mark.parametrize("arc", [0.0, 90.0, 200.0])
@pytest.mark.parametrize("tilt_index", [0, 30, -1])
def test_both_models_reproduce_the_rig_planes(arc, tilt_index):
    scan = rig_scan(CONFIG, arc_deg=arc, turntable_deg=35.0)
    n, c = scan.normal[tilt_index], scan.offset[tilt_index]
    line = exact_line(n, c)
    for angle in (scan.angle_deg[tilt_index], None):
        got_n, got_c = sheet_from_line(line, source_mm=scan.source_mm, angle_deg=angle)
        np.testing.assert_allclose(got_n, n, atol=1e-12)
        assert got_c == pytest.approx(c, abs=1e-9)
    # The emitter lies in its sheet.
    assert n @ scan.source_mm == pytest.approx(c, abs=1e-9)


def test_line_orientation_does_not_matter():
    scan = rig_scan(CONFIG, arc_deg=60.0)
    line = exact_line(scan.normal[5], scan.offset[5])
    flipped = LaserLine(-line.normal, -line.rho_mm, 50, 50, 0.0, 100.0, LineReason.OK)
    a = sheet_from_line(line, source_mm=scan.source_mm, angle_deg=40.0)
    b = sheet_from_line(flipped, source_mm=scan.source_mm, angle_deg=40.0)
    np.testing.assert_allclose(a[0], b[0])
    assert a[1] == pytest.approx(b[1])
    assert a[0][2] == pytest.approx(np.cos(np.deg2rad(40.0)))


def test_plane_interpolation_and_missing_frames():
    # Parallel planes z-tilted at 45°, moving 2 mm per frame; frame 3 has no line.
    m = np.array([1.0, 0.0])
    lines = [LaserLine(m, 2.0 * i, 50, 50, 0.0, 100.0, LineReason.OK) for i in range(6)]
    lines[3] = LaserLine(np.zeros(2), 0.0, 0, 0, 0.0, 0.0, LineReason.NO_CANDIDATES)
    planes = scan_planes(lines, source_mm=[500.0, 0, 500.0], angle_deg=45.0)
    assert planes.valid.tolist() == [True, True, True, False, True, True]
    n, c, ok = planes.at(np.array([0.0, 1.5, 2.0, 2.5, 3.0, 3.5, 4.5, 5.0, -0.1, 5.1]))
    assert ok.tolist() == [True, True, True, False, False, False, True, True, False, False]
    # Halfway between frames 1 and 2: the strip at x = 3 mm.
    np.testing.assert_allclose(n[1], [-np.sqrt(0.5), 0, np.sqrt(0.5)], atol=1e-12)
    assert c[1] / -np.sqrt(0.5) == pytest.approx(3.0)
    assert np.all(n[~ok] == 0) and np.all(c[~ok] == 0)


def test_invalid_sheet_inputs():
    line = LaserLine(np.array([1.0, 0]), 0.0, 50, 50, 0.0, 100.0, LineReason.OK)
    with pytest.raises(MdfError, match="angle must be in"):
        sheet_from_line(line, source_mm=[1.0, 0, 1.0], angle_deg=0.0)
    with pytest.raises(MdfError, match="above the plate"):
        sheet_from_line(line, source_mm=[1.0, 0, -1.0])
    bad = LaserLine(np.zeros(2), 0.0, 0, 0, 0.0, 0.0, LineReason.SHORT)
    with pytest.raises(MdfError, match="SHORT"):
        sheet_from_line(bad, source_mm=[1.0, 0, 1.0])
    with pytest.raises(MdfError, match="at least one frame"):
        scan_planes([], source_mm=[1.0, 0, 1.0])


def test_tetrahedron_weight():
    source, camera, strip = np.array([0, -300.0, 400]), np.array([0, 500.0, 600]), [1.0, 0]
    # Volume = |det(p1 - s, p2 - s, c - s)| / 6, by hand for this layout:
    # the base triangle (p1, p2, s) and the camera's distance from its plane.
    p1, p2 = np.array([-50.0, 0, 0]), np.array([50.0, 0, 0])
    area = 0.5 * np.linalg.norm(np.cross(p2 - p1, source - p1))
    normal = np.cross(p2 - p1, source - p1)
    height = abs((camera - p1) @ normal) / np.linalg.norm(normal)
    w = tetrahedron_weight(source, camera, strip, half_length_mm=50.0)
    assert w == pytest.approx(area * height / 3)
    # A camera in the laser plane through the centre line triangulates nothing.
    in_plane = 2.0 * source
    assert tetrahedron_weight(source, in_plane, strip, half_length_mm=50.0) == pytest.approx(0)
    with pytest.raises(MdfError, match="strip_direction"):
        tetrahedron_weight(source, camera, [0.0, 0.0], half_length_mm=50.0)


@given(
    theta=st.floats(1, 89),
    phi=st.floats(0, 360),
    rho=st.floats(-80, 80),
    psi=st.floats(0, 360),
    angle=st.one_of(st.none(), st.floats(0.5, 90)),
)
def test_planes_are_finite_unit_and_contain_the_line(theta, phi, rho, psi, angle):
    source = 500.0 * np.array(
        [
            np.sin(np.deg2rad(theta)) * np.cos(np.deg2rad(phi)),
            np.sin(np.deg2rad(theta)) * np.sin(np.deg2rad(phi)),
            np.cos(np.deg2rad(theta)),
        ]
    )
    m = np.array([np.cos(np.deg2rad(psi)), np.sin(np.deg2rad(psi))])
    line = LaserLine(m, rho, 50, 50, 0.0, 100.0, LineReason.OK)
    n, c = sheet_from_line(line, source_mm=source, angle_deg=angle)
    assert np.all(np.isfinite(n)) and np.isfinite(c)
    assert np.linalg.norm(n) == pytest.approx(1.0)
    assert n[2] >= 0
    on_line = np.array([*(m * rho), 0.0])
    along = np.array([-m[1], m[0], 0.0])
    assert n @ on_line == pytest.approx(c, abs=1e-6)
    assert n @ (on_line + 30 * along) == pytest.approx(c, abs=1e-6)
