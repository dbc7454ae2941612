"""The compiled pieces of a tracked registration against the numpy they replaced: the edge
fits' level medians, the marker bits, the homography's DLT, Gauss–Newton steps and noise
gain, and the float32 texels of the pinhole sampling."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from scipy import ndimage
from scipy.optimize import least_squares

from processing.registration import PlaneHomography, Reason, Region, marker_corners_mm, rectify
from processing.registration._edges import _median
from processing.registration._gauss_newton import fit_homography, noise_gain
from processing.registration._markers import to_gray
from processing.registration._predicted import _marker_bits, _reads_as
from rig.geometry import texel_centers_mm
from tests.processing.registration.plate_frames import project


@pytest.mark.parametrize("n", [1, 2, 7, 162, 163])
def test_the_level_median_is_numpys_for_noisy_tied_and_flat_levels(n):
    rng = np.random.default_rng(n)
    noisy = rng.normal(40.0, 3.0, n)
    tied = rng.integers(0, 4, n).astype(np.float64)  # few distinct values
    flat = np.full(n, 255.0)  # a saturated plate
    for levels in (noisy, tied, flat, np.sort(noisy), np.sort(noisy)[::-1]):
        work = np.concatenate([levels, [np.nan]])  # past n: never read
        assert _median(work, n) == np.median(levels)
        np.testing.assert_array_equal(np.sort(work[:n]), np.sort(levels))  # reordered only


def _numpy_reads_as(gray, quads, bits, modules):
    """The numpy reading of marker bits that the compiled pass replaced."""
    cells = (np.arange(-1, modules + 1) + 0.5) / modules
    u, v = np.meshgrid(cells, cells)
    u, v = u.ravel()[None, :, None], v.ravel()[None, :, None]
    p0, p1, p2, p3 = (quads[:, k] for k in range(4))
    s, d1, d2 = p0 - p1 + p2 - p3, p1 - p2, p3 - p2
    den = d1[:, 0] * d2[:, 1] - d2[:, 0] * d1[:, 1]
    g = (s[:, 0] * d2[:, 1] - d2[:, 0] * s[:, 1]) / den
    h = (d1[:, 0] * s[:, 1] - s[:, 0] * d1[:, 1]) / den
    a, b = p1 - p0 + g[:, None] * p1, p3 - p0 + h[:, None] * p3
    w = g[:, None, None] * u + h[:, None, None] * v + 1.0
    points = ((a[:, None, :] * u + b[:, None, :] * v + p0[:, None, :]) / w).reshape(-1, 2)
    n = modules + 2
    levels = ndimage.map_coordinates(
        gray, [points[:, 1], points[:, 0]], order=1, mode="nearest"
    ).reshape(-1, n, n)
    quiet = np.median(levels[:, _ring(n)], axis=1)
    border = levels[:, 1:-1, 1:-1][:, _ring(n - 2)]
    threshold = 0.5 * (quiet + np.median(border, axis=1))
    inner = levels[:, 2:-2, 2:-2] > threshold[:, None, None]
    return (
        (quiet > threshold)
        & (border < threshold[:, None]).all(axis=1)
        & (inner == bits).all(axis=(1, 2))
    )


def _ring(n):
    ring = np.ones((n, n), bool)
    ring[1:-1, 1:-1] = False
    return ring


def test_marker_bits_read_as_their_ids_and_not_as_others(frames, rig_config):
    """Every marker of a frame reads as its own bits through its true corners, and as
    no other marker's; a marker shifted by half its side does not read."""
    frame, G, _ = frames("cam0", 0.0)
    holder = rig_config.holder
    gray = to_gray(frame)
    quads = project(G, marker_corners_mm(holder))
    bits = _marker_bits(holder)
    modules = bits.shape[1] + 2
    own = _reads_as(gray, quads, bits, modules)
    assert own.sum() >= 12
    np.testing.assert_array_equal(own, _numpy_reads_as(gray, quads, bits, modules))
    others = _reads_as(gray, quads, np.roll(bits, 1, axis=0), modules)
    assert not others.any()
    shifted = quads + 0.5 * (quads[:, 1:2] - quads[:, 0:1])
    assert not _reads_as(gray, shifted, bits, modules).any()


def _plate_and_image(seed=0, noise_px=0.2):
    rng = np.random.default_rng(seed)
    plane = rng.uniform(-40.0, 40.0, (48, 2))
    H = np.array([[9.0, 0.6, 256.0], [-0.4, -8.5, 192.0], [2e-3, -1e-3, 1.0]])
    hom = np.column_stack([plane, np.ones(len(plane))]) @ H.T
    image = hom[:, :2] / hom[:, 2:] + rng.normal(0.0, noise_px, (len(plane), 2))
    return plane, image


def test_the_compiled_fit_reaches_opencvs_least_squares_minimum():
    """From the compiled DLT the Gauss–Newton steps end where the reprojection error is
    least: OpenCV's fit refined by Levenberg–Marquardt to float64 precision."""
    plane, image = _plate_and_image()
    H = fit_homography(plane, image)
    assert np.linalg.norm(H) == pytest.approx(1.0)
    # OpenCV's fit (its Levenberg–Marquardt on float32 points) polished in float64.
    reference, _ = cv2.findHomography(plane, image, 0)

    def residual(h):
        hom = np.column_stack([plane, np.ones(len(plane))]) @ h.reshape(3, 3).T
        return (hom[:, :2] / hom[:, 2:] - image).ravel()

    best = least_squares(residual, (reference / reference[2, 2]).ravel(), xtol=1e-15, ftol=1e-15)
    expected = best.x.reshape(3, 3) / np.linalg.norm(best.x)
    np.testing.assert_allclose(H, expected * np.sign(expected[2, 2]), atol=1e-9)
    assert np.sum(residual(H.ravel()) ** 2) <= np.sum(residual(best.x) ** 2) * (1 + 1e-9)


def test_degenerate_points_give_the_identity_not_nan():
    plane = np.zeros((8, 2))
    image = np.tile([[10.0, 20.0]], (8, 1))
    np.testing.assert_array_equal(fit_homography(plane, image), np.eye(3))


def test_the_noise_gain_is_the_covariance_formula_in_numpy():
    plane, image = _plate_and_image(seed=1)
    H = fit_homography(plane, image)
    corners = np.array([[-30.0, 30.0], [30.0, 30.0], [30.0, -30.0], [-30.0, -30.0]])
    basis = np.linalg.svd(H.reshape(1, 9))[2][1:].T

    def jacobian(points):
        hom = np.column_stack([points, np.ones(len(points))]) @ H.T
        w, (u, v) = hom[:, 2], (hom[:, :2] / hom[:, 2:]).T
        rows = np.zeros((2 * len(points), 9))
        base = np.column_stack([points, np.ones(len(points))]) / w[:, None]
        rows[: len(points), 0:3], rows[len(points) :, 3:6] = base, base
        rows[: len(points), 6:9] = -u[:, None] * base
        rows[len(points) :, 6:9] = -v[:, None] * base
        return rows @ basis

    J, Js = jacobian(plane), jacobian(corners)
    variance = np.einsum("ij,jk,ik->i", Js, np.linalg.inv(J.T @ J), Js)
    assert noise_gain(H, plane, corners) == pytest.approx(np.sqrt(np.mean(variance) * 2.0))


def test_texels_off_the_frame_read_zero_and_the_grid_follows_the_region():
    """The pinhole path writes float32 texels straight from the compiled pass: those whose
    footprint leaves the frame are zero and flagged; the kept texel grids of two regions
    are each their own (the box of bilinear samples of a linear ramp is the ramp)."""
    frame = np.add.outer(np.arange(48.0), 2.0 * np.arange(64.0))[:, :, None]  # 48 × 64
    H = np.array([[2.0, 0.0, 10.0], [0.0, -2.0, 24.0], [0.0, 0.0, 1.0]])  # 1 mm = 2 px
    empty = np.zeros(0, np.int64)
    hom = PlaneHomography(
        H, np.linalg.inv(H), True, Reason.OK, empty, np.zeros(0), 0.0, 0.0, empty
    )  # the sample square's −x part (x < −5.25 mm) lies left of the frame
    whole = rectify(frame, hom, sample_mm=40.0, size=16)
    valid = whole.valid
    assert valid.any() and not valid.all()
    assert whole.texture.dtype == np.float32
    np.testing.assert_array_equal(whole.texture[~valid], 0.0)
    for center in ((4.0, 2.0), (8.0, -3.0)):
        part = rectify(frame, hom, sample_mm=40.0, size=8, region=Region(center, 8.0))
        assert part.valid.all()
        xy = texel_centers_mm(8.0, 8) + np.array(center)
        col, row = 2.0 * xy[..., 0] + 10.0, -2.0 * xy[..., 1] + 24.0
        np.testing.assert_allclose(part.texture[..., 0], row + 2.0 * col, rtol=1e-6)
