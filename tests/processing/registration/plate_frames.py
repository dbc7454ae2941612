"""Synthetic frames of the holder plate with a known plate→image homography.

The plate is drawn analytically (no resampling of a bitmap): every pixel of a
4× supersampled image is mapped back to the plate through the true homography
(and lens distortion), the pattern is evaluated there, and the supersamples
are box-averaged, like a sensor integrating over its pixels. The markers
follow the convention of ``docs/btf.md``.
"""

from __future__ import annotations

import cv2
import numpy as np

from processing.registration import marker_corners_mm
from rig.camera import PinholeCamera
from rig.config import Holder
from rig.geometry import texel_centers_mm
from rig.kinematics import rotate_z

PLATE_WHITE = 0.9
INK = 0.05
BACKGROUND = 0.02


def sample_texture(x_mm: np.ndarray, y_mm: np.ndarray) -> np.ndarray:
    """The known sample albedo (band-limited, wavelengths ≥ 8 mm), RGB."""
    base = 0.45 + 0.2 * np.sin(2 * np.pi * x_mm / 17.0) * np.cos(2 * np.pi * y_mm / 11.0)
    ripple = 0.1 * np.sin(2 * np.pi * (x_mm + 2 * y_mm) / 23.0)
    return np.stack([base + ripple, base, base - ripple], axis=-1)


def _marker_bitmaps(holder: Holder) -> list[np.ndarray]:
    dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, holder.aruco_dictionary))
    modules = dictionary.markerSize + 2
    n = len(holder.marker_centers_mm())
    return [cv2.aruco.generateImageMarker(dictionary, i, modules, borderBits=1) for i in range(n)]


def _plate_points(plane_to_image, cols, rows, camera):
    """Plate (x, y) mm of image points (broadcast 2-D arrays); far away if behind."""
    if camera is not None and np.any(camera.dist):
        pix = np.stack(np.broadcast_arrays(cols, rows), axis=-1)
        und = cv2.undistortPoints(
            pix.reshape(-1, 1, 2),
            camera.K,
            camera.dist,
            P=camera.K,
            criteria=(cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-10),
        ).reshape(pix.shape)
        cols, rows = und[..., 0].astype(np.float64), und[..., 1].astype(np.float64)
    a = np.linalg.inv(plane_to_image)
    w = a[2, 0] * cols + a[2, 1] * rows + a[2, 2]
    # w is 1/depth up to the sign of G[2, 2] (the depth of the plate's origin).
    ahead = w * np.sign(plane_to_image[2, 2]) > 0
    w = np.where(ahead, w, 1.0)
    x = np.where(ahead, (a[0, 0] * cols + a[0, 1] * rows + a[0, 2]) / w, 1e9)
    y = np.where(ahead, (a[1, 0] * cols + a[1, 1] * rows + a[1, 2]) / w, 1e9)
    return x, y


def _render_block(holder, G, camera, rows_px, cols_px, s, rng, *, markers=True) -> np.ndarray:
    """(len(rows_px), len(cols_px), 3) pixel values, s×s jittered supersamples each."""
    h, w = len(rows_px), len(cols_px)
    cols = (cols_px[:, None] + (np.arange(s) + rng.random((w, s))) / s - 0.5).reshape(1, -1)
    rows = (rows_px[:, None] + (np.arange(s) + rng.random((h, s))) / s - 0.5).reshape(-1, 1)
    x, y = _plate_points(G, cols, rows, camera)
    half_plate = holder.plate_mm / 2
    gray = np.where((np.abs(x) <= half_plate) & (np.abs(y) <= half_plate), PLATE_WHITE, BACKGROUND)
    bitmaps = _marker_bitmaps(holder) if markers else []
    for quad, bitmap in zip(marker_corners_mm(holder), bitmaps, strict=False):
        modules = bitmap.shape[0]
        u = (x - quad[0, 0]) / holder.marker_mm  # 0..1 along bitmap columns (+x)
        v = (quad[0, 1] - y) / holder.marker_mm  # 0..1 along bitmap rows (−y)
        inside = (u >= 0) & (u < 1) & (v >= 0) & (v < 1)
        if not inside.any():
            continue
        col = np.clip((u * modules).astype(int), 0, modules - 1)
        row = np.clip((v * modules).astype(int), 0, modules - 1)
        gray = np.where(inside, np.where(bitmap[row, col] > 0, PLATE_WHITE, INK), gray)
    half = holder.sample_mm / 2
    in_sample = (np.abs(x) < half) & (np.abs(y) < half)
    gray = np.where(in_sample, 0.0, gray)

    def pixel_mean(values: np.ndarray) -> np.ndarray:
        # rows are (pixel row, sub row) in order, so a reshape averages blocks.
        return values.reshape(h, s, w, s).mean(axis=(1, 3))

    # The texture is smooth on the scale of a pixel: evaluate it once per
    # pixel, at the mean position of the pixel's supersamples in the sample.
    coverage = pixel_mean(in_sample.astype(np.float64))
    weight = np.maximum(coverage, 1e-12)
    tx = pixel_mean(np.where(in_sample, x, 0.0)) / weight
    ty = pixel_mean(np.where(in_sample, y, 0.0)) / weight
    texture = sample_texture(tx, ty) * coverage[..., None]
    return pixel_mean(gray)[..., None] + texture


def render_plate(
    holder: Holder,
    plane_to_image: np.ndarray,
    width: int,
    height: int,
    *,
    camera: PinholeCamera | None = None,
    supersample: int = 4,
    marker_supersample: int = 10,
    seed: int = 0,
) -> np.ndarray:
    """(height, width, 3) float32 frame of the plate seen through ``plane_to_image``.

    ``plane_to_image`` maps (x_mm, y_mm, 1) to undistorted pixels; with a
    ``camera`` the frame is distorted by its Brown–Conrady coefficients.
    Supersamples are jittered within their strata, so the pixel coverage of an
    edge is unbiased at any sub-pixel phase (a regular grid shifts edges by up
    to 1/(2s) px); the pixels around each marker are rendered again with
    ``marker_supersample``² samples so that the marker edges, whose positions
    the tests check to < 0.1 px, carry little rendering noise (the markers are
    drawn only there).
    """
    rng = np.random.default_rng(seed)
    G = plane_to_image
    frame = _render_block(
        holder, G, camera, np.arange(height, dtype=np.float64),
        np.arange(width, dtype=np.float64), supersample, rng, markers=False,
    )  # fmt: skip
    for quad in marker_corners_mm(holder):
        grown = quad + 0.25 * (quad - quad.mean(axis=0))  # the quiet zone too
        px = project(G, grown)
        if camera is not None and np.any(camera.dist):
            px = camera_distort(camera, px)
        r0, r1 = np.clip([px[:, 1].min() - 3, px[:, 1].max() + 4], 0, height).astype(int)
        c0, c1 = np.clip([px[:, 0].min() - 3, px[:, 0].max() + 4], 0, width).astype(int)
        if r1 <= r0 or c1 <= c0:
            continue
        frame[r0:r1, c0:c1] = _render_block(
            holder, G, camera, np.arange(r0, r1, dtype=np.float64),
            np.arange(c0, c1, dtype=np.float64), marker_supersample, rng,
        )  # fmt: skip
    return frame.astype(np.float32)


def camera_distort(camera: PinholeCamera, pixels: np.ndarray) -> np.ndarray:
    """Raw (distorted) pixels of undistorted ``pixels`` (n, 2)."""
    K = camera.K
    normalised = np.linalg.solve(K[:2, :2], (pixels - K[:2, 2]).T).T
    rays = np.column_stack([normalised, np.ones(len(pixels))])
    raw, _ = cv2.projectPoints(rays, np.zeros(3), np.zeros(3), K, camera.dist)
    return raw.reshape(-1, 2)


def camera_homography(camera: PinholeCamera, turntable_deg: float = 0.0) -> np.ndarray:
    """Plane (sample frame, mm) → undistorted pixel homography of a rig camera."""
    rot = rotate_z(np.eye(3), turntable_deg)  # rows: sample axes in the world frame
    R = camera.R @ rot.T
    G = camera.K @ np.column_stack([R[:, 0], R[:, 1], camera.t])
    return G / G[2, 2]


def texel_truth(sample_mm: float, n: int, *, oversample: int = 8) -> np.ndarray:
    """(n, n, 3) texel-area averages of ``sample_texture`` on the shared grid."""
    step = sample_mm / n
    sub = ((np.arange(oversample) + 0.5) / oversample - 0.5) * step
    centres = texel_centers_mm(sample_mm, n)
    x = centres[..., 0][..., None, None] + sub[None, None, None, :]
    y = centres[..., 1][..., None, None] + sub[None, None, :, None]
    x, y = np.broadcast_arrays(x, y)
    return sample_texture(x, y).mean(axis=(2, 3))


def project(G: np.ndarray, points_mm: np.ndarray) -> np.ndarray:
    """Undistorted pixels of (..., 2) plate points through the homography G."""
    pts = np.asarray(points_mm, dtype=np.float64)
    hom = np.concatenate([pts, np.ones((*pts.shape[:-1], 1))], axis=-1) @ G.T
    return hom[..., :2] / hom[..., 2:3]
