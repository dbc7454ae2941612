"""Camera calibration with a ChArUco board on the turntable.

Each camera sees the board at several turntable angles (and, for intrinsics,
at a few tilts). OpenCV 5's ``CharucoDetector`` finds the chessboard corners,
``board.matchImagePoints`` pairs them with their 3D board points, and
``cv2.calibrateCamera`` fits K, the Brown–Conrady distortion and a board pose
per image. Images whose own reprojection error is far above the rest are
rejected with the reason and the fit repeated. The turntable axis follows from
how the board turns between images: the common rotation axis of the relative
rotations, through the centre of the circle the board origin travels on.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from rig.errors import RigError

__all__ = [
    "CameraCalibration",
    "CameraCalibrationError",
    "CharucoBoardSpec",
    "CharucoView",
    "TurntableAxis",
    "calibrate_intrinsics",
    "detect_charuco",
    "turntable_axis",
]


class CameraCalibrationError(RigError):
    """The board images cannot give a trustworthy camera calibration."""


class CharucoBoardSpec(BaseModel):
    """The printed ChArUco board."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    squares_x: int = Field(9, ge=3)
    squares_y: int = Field(7, ge=3)
    square_mm: float = Field(15.0, gt=0)
    marker_mm: float = Field(11.0, gt=0)
    dictionary: str = "DICT_5X5_100"

    def board(self) -> cv2.aruco.CharucoBoard:
        if self.marker_mm >= self.square_mm:
            raise CameraCalibrationError(
                f"marker_mm ({self.marker_mm}) must be smaller than square_mm ({self.square_mm})"
            )
        try:
            dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, self.dictionary))
        except AttributeError:
            raise CameraCalibrationError(
                f"unknown ArUco dictionary {self.dictionary!r}; use a cv2.aruco DICT_* name"
            ) from None
        return cv2.aruco.CharucoBoard(
            (self.squares_x, self.squares_y), self.square_mm, self.marker_mm, dictionary
        )


@dataclass(frozen=True)
class CharucoView:
    """Board corners found in one image: image points and their board points (mm)."""

    image_points: np.ndarray  # (n, 2) float32
    object_points: np.ndarray  # (n, 3) float32
    ids: np.ndarray  # (n,) int


@dataclass(frozen=True)
class CameraCalibration:
    """Intrinsics and per-image board poses of one camera.

    ``rms_px`` is the overall reprojection RMS over the images kept;
    ``per_image_rms_px`` maps each image in which the board was found to its
    RMS (outliers keep their error from the first fit); ``rejected`` maps
    image index → reason.
    """

    K: np.ndarray
    dist: np.ndarray
    image_size: tuple[int, int]
    rms_px: float
    per_image_rms_px: dict[int, float]
    rvecs: tuple[np.ndarray, ...]
    tvecs: tuple[np.ndarray, ...]
    kept: tuple[int, ...]
    rejected: dict[int, str] = field(default_factory=dict)


@dataclass(frozen=True)
class TurntableAxis:
    """The turntable axis in the camera frame: a point on it and its direction."""

    point: np.ndarray
    direction: np.ndarray
    angle_residual_deg: float


def detect_charuco(image, spec: CharucoBoardSpec, *, min_corners: int = 12) -> CharucoView | None:
    """Find the board's chessboard corners; None when fewer than ``min_corners``
    (a board seen at a grazing angle shows only a few, and they are imprecise)."""
    img = np.asarray(image)
    if img.ndim == 3:
        img = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY if img.shape[2] == 3 else cv2.COLOR_BGRA2GRAY)
    if img.dtype != np.uint8:
        raise CameraCalibrationError(f"detect_charuco: expected uint8 images, got {img.dtype}")
    board = spec.board()
    detector = cv2.aruco.CharucoDetector(board)
    corners, ids, _, _ = detector.detectBoard(img)
    if ids is None or len(ids) < min_corners:
        return None
    obj, imgp = board.matchImagePoints(corners, ids)
    return CharucoView(
        imgp.reshape(-1, 2).astype(np.float32), obj.reshape(-1, 3).astype(np.float32), ids.ravel()
    )


def _per_image_rms(views, K, dist, rvecs, tvecs) -> np.ndarray:
    errors = []
    for view, r, t in zip(views, rvecs, tvecs, strict=True):
        proj, _ = cv2.projectPoints(view.object_points, r, t, K, dist)
        errors.append(np.sqrt(np.mean(np.sum((proj.reshape(-1, 2) - view.image_points) ** 2, 1))))
    return np.array(errors)


def calibrate_intrinsics(
    views, image_size: tuple[int, int], *, outlier_factor: float = 3.0, min_views: int = 3
) -> CameraCalibration:
    """Fit K and distortion to board views; reject outlier images and refit.

    Parameters
    ----------
    views : sequence of CharucoView or None (None = board not found, rejected)
    image_size : (width, height) in pixels
    outlier_factor : an image whose RMS exceeds this × the median RMS (and
        0.5 px) is rejected with the reason
    """
    rejected: dict[int, str] = {}
    usable = []
    for i, view in enumerate(views):
        if view is None:
            rejected[i] = "board not found (too few corners)"
        elif len(view.image_points) < 12:
            rejected[i] = f"only {len(view.image_points)} corners"
        else:
            usable.append(i)
    if len(usable) < min_views:
        raise CameraCalibrationError(
            f"only {len(usable)} usable board image(s), need ≥ {min_views}: {rejected}"
        )

    def fit(indices):
        obj = [views[i].object_points for i in indices]
        img = [views[i].image_points for i in indices]
        rms, K, dist, rvecs, tvecs = cv2.calibrateCamera(
            obj, img, image_size, None, None, flags=cv2.CALIB_FIX_K3
        )
        return rms, K, dist.ravel(), rvecs, tvecs

    rms, K, dist, rvecs, tvecs = fit(usable)
    first = dict(zip(usable, _per_image_rms([views[i] for i in usable], K, dist, rvecs, tvecs),
                     strict=True))  # fmt: skip
    limit = max(outlier_factor * float(np.median(list(first.values()))), 0.5)
    outliers = [i for i, e in first.items() if e > limit]
    if outliers and len(usable) - len(outliers) >= min_views:
        for i in outliers:
            rejected[i] = f"reprojection RMS {first[i]:.2f} px > {limit:.2f} px (outlier)"
        usable = [i for i in usable if i not in rejected]
        rms, K, dist, rvecs, tvecs = fit(usable)
    final = _per_image_rms([views[i] for i in usable], K, dist, rvecs, tvecs)
    per_image = {**first, **dict(zip(usable, final, strict=True))}
    return CameraCalibration(
        K, dist, tuple(image_size), float(rms), {i: float(e) for i, e in per_image.items()},
        tuple(rvecs), tuple(tvecs), tuple(usable), rejected,
    )  # fmt: skip


def turntable_axis(rvecs, tvecs) -> TurntableAxis:
    """The turntable axis (camera frame) from board poses at several turntable angles.

    Every relative rotation R_i R_0ᵀ turns about the same axis, and every
    board point moves on a circle around it. Needs ≥ 3 poses with distinct
    angles; a full turn of the turntable gives the best-conditioned axis.
    """
    if len(rvecs) < 3:
        raise CameraCalibrationError(f"need ≥ 3 board poses to find the axis, got {len(rvecs)}")
    Rs = [cv2.Rodrigues(np.asarray(r, dtype=np.float64))[0] for r in rvecs]
    axes, angles = [], []
    for R in Rs[1:]:
        rel, _ = cv2.Rodrigues(R @ Rs[0].T)
        angle = np.linalg.norm(rel)
        if angle < np.deg2rad(2):
            continue
        axis = rel.ravel() / angle
        axes.append(axis if not axes or axis @ axes[0] > 0 else -axis)
        angles.append(angle)
    if len(axes) < 2:
        raise CameraCalibrationError("the board poses differ by < 2°: turn the turntable further")
    direction = np.mean(axes, axis=0)
    direction /= np.linalg.norm(direction)
    spread = max(np.rad2deg(np.arccos(np.clip(a @ direction, -1, 1))) for a in axes)
    # Each pose is pose 0 turned about the axis: t_i − c = Q_i (t_0 − c) with
    # Q_i = R_i R_0ᵀ, i.e. (I − Q_i) c = t_i − Q_i t_0 — linear in c, determined
    # up to a shift along the axis (fixed at the boards' mean height).
    t = [np.asarray(tv, dtype=np.float64).ravel() for tv in tvecs]
    rows, rhs = [], []
    for R, ti in zip(Rs[1:], t[1:], strict=True):
        Q = R @ Rs[0].T
        rows.append(np.eye(3) - Q)
        rhs.append(ti - Q @ t[0])
    c, *_ = np.linalg.lstsq(np.vstack(rows), np.concatenate(rhs), rcond=None)
    c_perp = c - (c @ direction) * direction
    point = c_perp + np.mean([ti @ direction for ti in t]) * direction
    return TurntableAxis(point, direction, float(spread))
