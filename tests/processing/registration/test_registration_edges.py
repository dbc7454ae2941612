"""The compiled edge-fit corner refinement against the per-edge numpy loop it replaced.

``edge_fit_loop`` below is that loop as it was (scipy's bilinear sampling,
numpy medians and trapezoids, an SVD per line), kept here as the reference:
the compiled kernel must give its corners to float precision, and keep the
initial corners of exactly the markers where the loop gave up.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from processing.registration import RegistrationError, aruco_dictionary, detect_markers
from processing.registration._edges import refine_corners
from processing.registration._markers import to_gray
from sim import Simulator
from studies.registration_views import registration_scene

_SPAN = (0.15, 0.85)
_STEPS_PER_PX = 8


def _edge_points(gray, p0, p1, outward, reach_px):
    length = float(np.linalg.norm(p1 - p0))
    n_normals = max(4, int(length * (_SPAN[1] - _SPAN[0])))
    t = np.linspace(_SPAN[0], _SPAN[1], n_normals)
    n_steps = max(9, int(2 * reach_px * _STEPS_PER_PX) | 1)
    offsets = np.linspace(-reach_px, reach_px, n_steps)
    base = p0[None, :] + t[:, None] * (p1 - p0)[None, :]
    pts = base[:, None, :] + offsets[None, :, None] * outward[None, None, :]
    profile = ndimage.map_coordinates(
        gray, [pts[..., 1].ravel(), pts[..., 0].ravel()], order=1, mode="nearest"
    ).reshape(pts.shape[:2])
    ends = max(1, n_steps // 6)
    dark = float(np.median(profile[:, :ends]))
    bright = float(np.median(profile[:, -ends:]))
    if bright - dark <= 0.2 * max(abs(bright), abs(dark), 1e-12):
        return np.zeros((0, 2))
    f = np.clip((profile - dark) / (bright - dark), 0.0, 1.0)
    clean = (f[:, :ends].max(axis=1) < 0.25) & (f[:, -ends:].min(axis=1) > 0.75)
    e = reach_px - np.trapezoid(f, offsets, axis=1)
    return (base + e[:, None] * outward[None, :])[clean]


def _fit_line(points):
    if len(points) < 3:
        return None
    centre = points.mean(axis=0)
    *_, vt = np.linalg.svd(points - centre, full_matrices=False)
    return vt[-1], float(vt[-1] @ centre)


def edge_fit_loop(gray, quad, modules):
    """The per-edge loop: refined (4, 2) corners of one marker, or None."""
    corners = np.asarray(quad, dtype=np.float64)
    for _ in range(2):
        centre = corners.mean(axis=0)
        lines = []
        for k in range(4):
            p0, p1 = corners[k], corners[(k + 1) % 4]
            direction = (p1 - p0) / max(np.linalg.norm(p1 - p0), 1e-12)
            outward = np.array([direction[1], -direction[0]])
            if outward @ (0.5 * (p0 + p1) - centre) < 0:
                outward = -outward
            far0, far1 = corners[(k + 3) % 4], corners[(k + 2) % 4]
            depth = 0.5 * abs(outward @ (far0 - p0) + outward @ (far1 - p1))
            line = _fit_line(_edge_points(gray, p0, p1, outward, 0.8 * depth / modules))
            if line is None:
                return None
            lines.append(line)
        new = np.empty((4, 2))
        for k in range(4):
            (n0, d0), (n1, d1) = lines[k - 1], lines[k]
            A = np.array([n0, n1])
            if abs(np.linalg.det(A)) < 1e-6:
                return None
            new[k] = np.linalg.solve(A, [d0, d1])
        sides = np.linalg.norm(corners - np.roll(corners, 1, axis=0), axis=1)
        if np.max(np.linalg.norm(new - corners, axis=1)) > sides.min() / modules:
            return None
        corners = new
    return corners


def _compare(gray, quads, modules) -> tuple[int, int]:
    """Assert the kernel matches the loop on every quad; (refined, kept) counts."""
    refined = refine_corners(gray, quads, modules=modules)
    assert refined.shape == quads.shape
    kept = 0
    for quad, got in zip(quads, refined, strict=True):
        expected = edge_fit_loop(gray, quad, modules)
        if expected is None:
            kept += 1
            np.testing.assert_array_equal(got, quad)
        else:
            np.testing.assert_allclose(got, expected, rtol=0, atol=1e-9)
    return len(quads) - kept, kept


def _opencv_quads(gray, holder) -> np.ndarray:
    return detect_markers(gray, holder, edge_refine=False).corners_px


@pytest.fixture(scope="module")
def modules(holder) -> int:
    return aruco_dictionary(holder).markerSize + 2


@pytest.mark.parametrize(("camera_id", "turntable_deg"), [("cam0", 0.0), ("cam5", 30.0)])
def test_kernel_matches_the_loop_on_plate_frames(frames, holder, modules, camera_id, turntable_deg):
    frame, _, _ = frames(camera_id, turntable_deg)
    gray = to_gray(frame)
    quads = _opencv_quads(gray, holder)
    refined, kept = _compare(gray, quads, modules)
    assert refined == len(quads) and kept == 0
    # Starting a fraction of a module off: the same corners; a module off: both give up.
    rng = np.random.default_rng(1)
    refined, _ = _compare(gray, quads + rng.uniform(-0.7, 0.7, quads.shape), modules)
    assert refined > len(quads) // 2
    shifted = quads + np.array([6.0, 0.0])
    refined, kept = _compare(gray, shifted, modules)
    assert kept > 0


def test_kernel_matches_the_loop_at_the_image_edge(frames, holder, modules):
    frame, _, _ = frames("cam0", 0.0)
    gray = to_gray(frame)
    quads = _opencv_quads(gray, holder)
    # Crop the frame a few pixels outside the leftmost markers, then through them:
    # their outer profiles run off the image and sample its edge pixels.
    left = quads[..., 0].min(axis=1).min()
    for margin_px in (1.0, 0.3, -0.6, -3.0):
        c0 = int(np.floor(left - margin_px))
        refined, _ = _compare(gray[:, c0:], quads - np.array([c0, 0.0]), modules)
        if margin_px > 0:
            assert refined == len(quads)
    # The top row of markers, cut through the middle: both give up on exactly those.
    top = quads[..., 1].min(axis=1)
    r0 = int(top.min() + 0.5 * np.ptp(quads[np.argmin(top), :, 1]))
    _, kept = _compare(gray[r0:], quads - np.array([0.0, r0]), modules)
    assert kept == np.sum(top < r0)


@pytest.mark.parametrize("sigma_px", [0.8, 2.0])
def test_kernel_matches_the_loop_on_blurred_corners(frames, holder, modules, sigma_px):
    frame, _, _ = frames("cam5", 30.0)
    quads = _opencv_quads(to_gray(frame), holder)
    blurred = ndimage.gaussian_filter(to_gray(frame), sigma_px)
    refined, _ = _compare(blurred, quads, modules)
    assert refined > 0


def test_kernel_matches_the_loop_on_a_saturated_frame(holder, modules):
    # The simulator's sensor clips at full scale: with a long exposure the white
    # plate around the markers saturates, flat, and its edges are clipped ramps.
    scene = registration_scene(0.25, effects=("noise", "saturation"))
    with Simulator(scene) as sim:
        lamps = [lamp.id for lamp in scene.rig.light_arc.lamps]
        frame = sim.render_state("cam2", lamps_on=lamps, exposure_s=0.1).image
    gray = to_gray(frame)
    assert np.mean(gray >= gray.max()) > 0.4  # the plate at full scale
    quads = _opencv_quads(gray, holder)
    assert len(quads) >= 4
    refined, _ = _compare(gray, quads, modules)
    assert refined > 0
    # A bright blob (a highlight) over one corner, clipped at full scale.
    rows, cols = np.indices(gray.shape)
    x, y = quads[0, 2]
    blob = np.exp(-((cols - x) ** 2 + (rows - y) ** 2) / (2 * 3.0**2))
    lit = np.minimum(gray + 2 * gray.max() * blob, gray.max())
    _compare(lit, quads, modules)


def test_refine_corners_rejects_bad_shapes():
    with pytest.raises(RegistrationError, match="quads"):
        refine_corners(np.zeros((8, 8)), np.zeros((4, 2)), modules=6)
    with pytest.raises(RegistrationError, match="gray"):
        refine_corners(np.zeros((8, 8, 3)), np.zeros((1, 4, 2)), modules=6)
