"""Camera calibration with a ChArUco board on the turntable.

Each camera sees the board at several turntable angles (and, for intrinsics,
at a few tilts). OpenCV 5's ``CharucoDetector`` finds the chessboard corners,
``board.matchImagePoints`` pairs them with their 3D board points, and
``cv2.calibrateCamera`` fits K, the Brown–Conrady distortion and a board pose
per image. Images whose own reprojection error is far above the rest are
rejected with the reason and the fit repeated. The turntable axis follows from
how the board turns between images: the common rotation axis of the relative
rotations, through the centre of the circle the board origin travels on.

On the rig the board stands on a wedge in the holder (``rig.targets``), so its
place in the turntable frame is known, and the turntable angle of each image is
recorded. :func:`calibrate_turntable_camera` uses that: every image's corners
are points of one rigid 3D object (the wedge turned by the recorded angles),
and one fit gives K, distortion and the camera's pose in the turntable frame —
17 unknowns for all images instead of 6 more per image, which pins the focal
length far better than independent board poses on a long lens.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np
from scipy.optimize import least_squares

from rig.errors import RigError
from rig.kinematics import rotate_z
from rig.targets import CharucoTarget

__all__ = [
    "CameraCalibration",
    "CameraCalibrationError",
    "CharucoView",
    "TurntableAxis",
    "TurntableCamera",
    "calibrate_intrinsics",
    "calibrate_turntable_camera",
    "detect_charuco",
    "turntable_axis",
]

# The board covers the middle of a long lens's view, where k2 and k3 move a
# corner by < 0.02 px: fit k1 and the tangential terms.
_FLAGS = cv2.CALIB_FIX_K2 | cv2.CALIB_FIX_K3


class CameraCalibrationError(RigError):
    """The board images cannot give a trustworthy camera calibration."""


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


def detect_charuco(image, spec: CharucoTarget, *, min_corners: int = 12) -> CharucoView | None:
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
            obj, img, image_size, None, None, flags=_FLAGS
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


@dataclass(frozen=True)
class TurntableCamera:
    """One camera calibrated on the turntable: intrinsics and pose (world frame).

    ``R, t`` map world (turntable at 0°) to camera: x_cam = R x + t.
    ``per_image_rms_px`` maps image index → RMS for the images kept;
    ``rejected`` maps image index → reason. ``axis_tilt_deg`` is the angle
    between the turntable axis found from the board's rotations alone and the
    world z axis of the fitted pose: a check of the recorded angles and the
    board's placement (near 0 when both hold; None when the kept images turn
    by too little to find an axis).
    """

    K: np.ndarray
    dist: np.ndarray
    R: np.ndarray
    t: np.ndarray
    image_size: tuple[int, int]
    rms_px: float
    per_image_rms_px: dict[int, float]
    rejected: dict[int, str]
    axis_tilt_deg: float | None

    @property
    def centre_mm(self) -> np.ndarray:
        """The camera's centre of projection in the world frame."""
        return -self.R.T @ self.t


def _world_points(view: CharucoView, board: CharucoTarget, turntable_deg: float) -> np.ndarray:
    R_bs, t_bs = board.board_pose()
    return rotate_z(view.object_points.astype(np.float64) @ R_bs.T + t_bs, turntable_deg)


def _obliquity_deg(rvec, tvec, board: CharucoTarget) -> float:
    """Angle between the board's normal and the ray from the camera to its centre."""
    R = cv2.Rodrigues(np.asarray(rvec, dtype=np.float64))[0]
    w, h = board.size_mm
    centre = R @ np.array([w / 2, h / 2, 0.0]) + np.asarray(tvec, dtype=np.float64).ravel()
    cosine = abs(float(R[:, 2] @ centre)) / float(np.linalg.norm(centre))
    return float(np.rad2deg(np.arccos(min(1.0, cosine))))


def calibrate_turntable_camera(
    views,
    turntable_deg,
    board: CharucoTarget,
    image_size: tuple[int, int],
    *,
    max_obliquity_deg: float = 50.0,
) -> TurntableCamera:
    """K, k1, p1, p2 and the world pose of a camera from board views at turntable angles.

    Parameters
    ----------
    views : sequence of CharucoView or None, one per image
    turntable_deg : the recorded turntable angle of each image
    board : the board and its wedge
    image_size : (width, height) in pixels
    max_obliquity_deg : images that see the board further than this from its
        normal are left out, with the reason (grazing views bias the corners)

    Starts from :func:`calibrate_intrinsics` (which also rejects outlier
    images), then fits all kept images jointly as one rigid object.
    """
    angles = np.asarray(turntable_deg, dtype=np.float64).ravel()
    if len(angles) != len(views):
        raise CameraCalibrationError(f"{len(views)} views but {len(angles)} turntable angles")
    first = calibrate_intrinsics(views, image_size)
    rejected = dict(first.rejected)
    kept = []
    for k, i in enumerate(first.kept):
        obliquity = _obliquity_deg(first.rvecs[k], first.tvecs[k], board)
        if obliquity > max_obliquity_deg:
            rejected[i] = (
                f"board seen {obliquity:.0f}° from its normal (grazing, > {max_obliquity_deg:g}°): "
                "its foreshortened corners are biased"
            )
        else:
            kept.append(i)
    if len(kept) < 3:
        raise CameraCalibrationError(
            f"only {len(kept)} board image(s) seen less obliquely than {max_obliquity_deg:g}°, "
            f"need ≥ 3: {rejected}"
        )
    world = [_world_points(views[i], board, angles[i]) for i in kept]
    image = [views[i].image_points.astype(np.float64) for i in kept]
    # Start: the camera pose the best image implies.
    best = int(np.argmin([first.per_image_rms_px[i] for i in kept]))
    _, rvec, tvec = cv2.solvePnP(world[best], image[best], first.K, first.dist)
    x0 = np.concatenate([
        [first.K[0, 0], first.K[1, 1], first.K[0, 2], first.K[1, 2]],
        first.dist[[0, 2, 3]], rvec.ravel(), tvec.ravel(),
    ])  # fmt: skip
    all_world, all_image = np.vstack(world), np.vstack(image)

    def unpack(x):
        K = np.array([[x[0], 0, x[2]], [0, x[1], x[3]], [0, 0, 1.0]])
        return K, np.array([x[4], 0.0, x[5], x[6], 0.0]), x[7:10], x[10:13]

    def residuals(x):
        K, dist, rvec, tvec = unpack(x)
        proj, _ = cv2.projectPoints(all_world, rvec, tvec, K, dist)
        return (proj.reshape(-1, 2) - all_image).ravel()

    fit = least_squares(residuals, x0, x_scale="jac", method="lm")
    K, dist, rvec, tvec = unpack(fit.x)
    err = np.sqrt(np.sum(fit.fun.reshape(-1, 2) ** 2, axis=1))
    bounds = np.cumsum([0] + [len(w) for w in world])
    per_image = {
        i: float(np.sqrt(np.mean(err[a:b] ** 2)))
        for i, a, b in zip(kept, bounds[:-1], bounds[1:], strict=True)
    }
    R = cv2.Rodrigues(rvec)[0]
    try:
        axis = turntable_axis(first.rvecs, first.tvecs)
        tilt = float(np.rad2deg(np.arccos(min(1.0, abs(float(axis.direction @ R[:, 2]))))))
    except CameraCalibrationError:  # the kept images turn by < 2°: no axis to compare
        tilt = None
    return TurntableCamera(
        K, dist, R, tvec.copy(), tuple(image_size), float(np.sqrt(np.mean(err**2))),
        per_image, rejected, tilt,
    )  # fmt: skip
