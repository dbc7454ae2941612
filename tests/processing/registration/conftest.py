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
import pytest

from processing.registration import marker_corners_mm
from rig.camera import PinholeCamera
from rig.config import Holder, default_rig_config
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


def render_plate(
    holder: Holder,
    plane_to_image: np.ndarray,
    width: int,
    height: int,
    *,
    camera: PinholeCamera | None = None,
    supersample: int = 4,
    seed: int = 0,
) -> np.ndarray:
    """(height, width, 3) float32 frame of the plate seen through ``plane_to_image``.

    ``plane_to_image`` maps (x_mm, y_mm, 1) to undistorted pixels; with a
    ``camera`` the frame is distorted by its Brown–Conrady coefficients. The
    supersamples are jittered within their strata (one random offset per
    sub-column and per sub-row), so the pixel coverage of an edge is unbiased
    at any sub-pixel phase: a regular grid would shift edges by up to 1/(2s) px.
    """
    s = supersample
    rng = np.random.default_rng(seed)
    cols = ((np.arange(width * s) + rng.random(width * s)) / s - 0.5)[None, :]
    rows = ((np.arange(height * s) + rng.random(height * s)) / s - 0.5)[:, None]
    a = np.linalg.inv(plane_to_image)
    if camera is not None and np.any(camera.dist):
        pix = np.stack(np.broadcast_arrays(cols, rows), axis=-1).reshape(-1, 1, 2)
        und = cv2.undistortPoints(
            pix,
            camera.K,
            camera.dist,
            P=camera.K,
            criteria=(cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-10),
        ).reshape(height * s, width * s, 2)
        cols, rows = und[..., 0].astype(np.float64), und[..., 1].astype(np.float64)
    w = a[2, 0] * cols + a[2, 1] * rows + a[2, 2]
    # w is 1/depth up to the sign of G[2, 2] (the depth of the plate's origin).
    ahead = w * np.sign(plane_to_image[2, 2]) > 0
    w = np.where(ahead, w, 1.0)
    x = np.where(ahead, (a[0, 0] * cols + a[0, 1] * rows + a[0, 2]) / w, 1e9)
    y = np.where(ahead, (a[1, 0] * cols + a[1, 1] * rows + a[1, 2]) / w, 1e9)

    half_plate = holder.plate_mm / 2
    gray = np.where((np.abs(x) <= half_plate) & (np.abs(y) <= half_plate), PLATE_WHITE, BACKGROUND)
    for quad, bitmap in zip(marker_corners_mm(holder), _marker_bitmaps(holder), strict=True):
        modules = bitmap.shape[0]
        # Only the supersamples inside the marker's image bounding box.
        hom = np.column_stack([quad, np.ones(4)]) @ plane_to_image.T
        box = (hom[:, :2] / hom[:, 2:3] + 0.5) * s
        r0, r1 = np.clip([box[:, 1].min() - 8, box[:, 1].max() + 8], 0, height * s).astype(int)
        c0, c1 = np.clip([box[:, 0].min() - 8, box[:, 0].max() + 8], 0, width * s).astype(int)
        u = (x[r0:r1, c0:c1] - quad[0, 0]) / holder.marker_mm  # 0..1 along bitmap columns
        v = (quad[0, 1] - y[r0:r1, c0:c1]) / holder.marker_mm  # 0..1 along bitmap rows (−y)
        inside = (u >= 0) & (u < 1) & (v >= 0) & (v < 1)
        col = np.clip((u * modules).astype(int), 0, modules - 1)
        row = np.clip((v * modules).astype(int), 0, modules - 1)
        ink = np.where(bitmap[row, col] > 0, PLATE_WHITE, INK)
        gray[r0:r1, c0:c1] = np.where(inside, ink, gray[r0:r1, c0:c1])
    half = holder.sample_mm / 2
    in_sample = (np.abs(x) < half) & (np.abs(y) < half)
    gray = np.where(in_sample, 0.0, gray)

    def pixel_mean(values: np.ndarray) -> np.ndarray:
        # rows are (pixel row, sub row) in order, so a reshape averages blocks.
        return values.reshape(height, s, width, s).mean(axis=(1, 3))

    # The texture is smooth on the scale of a pixel: evaluate it once per
    # pixel, at the mean position of the pixel's supersamples in the sample.
    coverage = pixel_mean(in_sample.astype(np.float64))
    weight = np.maximum(coverage, 1e-12)
    tx = pixel_mean(np.where(in_sample, x, 0.0)) / weight
    ty = pixel_mean(np.where(in_sample, y, 0.0)) / weight
    texture = sample_texture(tx, ty) * coverage[..., None]
    return (pixel_mean(gray)[..., None] + texture).astype(np.float32)


def camera_homography(camera: PinholeCamera, turntable_deg: float = 0.0) -> np.ndarray:
    """Plane (sample frame, mm) → undistorted pixel homography of a rig camera."""
    rot = rotate_z(np.eye(3), turntable_deg)  # rows: sample axes in the world frame
    R = camera.R @ rot.T
    G = camera.K @ np.column_stack([R[:, 0], R[:, 1], camera.t])
    return G / G[2, 2]


@pytest.fixture(scope="session")
def rig_config():
    return default_rig_config()


@pytest.fixture(scope="session")
def holder(rig_config) -> Holder:
    return rig_config.holder
