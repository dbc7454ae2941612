import cv2
import numpy as np
import pytest
from numpy.testing import assert_allclose

from calibration.cameras import (
    CameraCalibrationError,
    calibrate_intrinsics,
    detect_charuco,
    turntable_axis,
)
from rig.camera import PinholeCamera
from rig.config import default_rig_config
from rig.targets import CharucoTarget

# Simulated sessions, rendered targets or fits of seconds each: make test only, not make quick.
pytestmark = pytest.mark.slow

SPEC = CharucoTarget(square_mm=15.0, marker_mm=11.0)
PPMM = 12  # board texture resolution, pixels per mm
SUPERSAMPLE = 2
_nominal = default_rig_config().camera_model("cam2")
CAMERA = PinholeCamera(
    _nominal.K, np.array([-0.12, 0.08, 0.0005, -0.0003, 0.0]), _nominal.R, _nominal.t,
    _nominal.width, _nominal.height,
)  # fmt: skip
BOARD_W = SPEC.squares_x * SPEC.square_mm
BOARD_H = SPEC.squares_y * SPEC.square_mm
TEXTURE = SPEC.board().generateImage((int(BOARD_W * PPMM), int(BOARD_H * PPMM)), marginSize=0)


def _rot(axis, deg):
    return cv2.Rodrigues(np.asarray(axis, dtype=float) * np.deg2rad(deg))[0]


def _board_pose(turntable_deg, tilt_deg=0.0, tilt_y_deg=0.0):
    """Board → world: centred on the turntable axis, tilted (on a wedge), turned about z.

    OpenCV's board frame has z into the board, so the board is flipped about x
    to face the cameras above it.
    """
    tilt = _rot([1, 0, 0], tilt_deg) @ _rot([0, 1, 0], tilt_y_deg)
    R = _rot([0, 0, 1], turntable_deg) @ tilt @ _rot([1, 0, 0], 180)
    t = -R @ np.array([BOARD_W / 2, BOARD_H / 2, 0.0])
    return R, t


def _camera_rays():
    s = SUPERSAMPLE
    h, w = CAMERA.height * s, CAMERA.width * s
    yy, xx = np.mgrid[0:h, 0:w]
    pix = np.column_stack([(xx.ravel() + 0.5) / s - 0.5, (yy.ravel() + 0.5) / s - 0.5])
    return CAMERA.rays(pix)


RAYS = _camera_rays()  # the camera does not move: trace its rays once


def _render(R_b, t_b):
    s = SUPERSAMPLE
    h, w = CAMERA.height * s, CAMERA.width * s
    origin, d = RAYS
    o_b = R_b.T @ (origin - t_b)
    d_b = d @ R_b  # R_bᵀ d for each row
    hit = -o_b[2] / d_b[:, 2]
    b = o_b + hit[:, None] * d_b
    map_x = (b[:, 0] * PPMM - 0.5).reshape(h, w).astype(np.float32)
    map_y = (b[:, 1] * PPMM - 0.5).reshape(h, w).astype(np.float32)
    big = cv2.remap(TEXTURE, map_x, map_y, cv2.INTER_LINEAR, borderValue=200)
    return cv2.resize(big, (CAMERA.width, CAMERA.height), interpolation=cv2.INTER_AREA)


@pytest.fixture(scope="module")
def board_views():
    # Flat at several turntable angles (for the axis), and on a 30–35° wedge in
    # several directions: tilted views make the focal length observable.
    poses = [(a, 0.0, 0.0) for a in (0, 60, 120, 180, 240, 300)]
    poses += [(a, 35.0, 0.0) for a in (0, 90, 180, 270)] + [(45, -30.0, 0.0), (200, 0.0, 30.0)]
    views = [detect_charuco(_render(*_board_pose(*p)), SPEC) for p in poses]
    return poses, views


def test_intrinsics_and_pose_from_rendered_boards(board_views):
    poses, views = board_views
    cal = calibrate_intrinsics(views, (CAMERA.width, CAMERA.height))
    assert cal.rms_px < 0.1
    assert not cal.rejected
    assert_allclose(cal.K[0, 0], CAMERA.K[0, 0], rtol=0.005)
    assert_allclose(cal.K[1, 1], CAMERA.K[1, 1], rtol=0.005)
    # Camera position in the turntable frame from the flat pose at 0°.
    R_b, t_b = _board_pose(*poses[0])
    R_cb = cv2.Rodrigues(cal.rvecs[0])[0]
    center_board = -R_cb.T @ cal.tvecs[0].ravel()
    center_world = R_b @ center_board + t_b
    assert np.linalg.norm(center_world - CAMERA.center) < 1.0  # mm


def test_turntable_axis_from_flat_poses(board_views):
    poses, views = board_views
    cal = calibrate_intrinsics(views, (CAMERA.width, CAMERA.height))
    flat = [i for i, p in enumerate(poses) if p[1:] == (0.0, 0.0) and i in cal.kept]
    idx = [cal.kept.index(i) for i in flat]
    axis = turntable_axis([cal.rvecs[i] for i in idx], [cal.tvecs[i] for i in idx])
    true_dir = CAMERA.R @ np.array([0, 0, 1.0])
    assert abs(abs(axis.direction @ true_dir) - 1) < 1e-4
    # The axis passes through the turntable centre (world origin).
    origin_cam = CAMERA.t
    off = origin_cam - axis.point
    dist = np.linalg.norm(off - (off @ axis.direction) * axis.direction)
    assert dist < 1.0


def test_outlier_image_is_rejected_with_reason(board_views):
    _, views = board_views
    bad = views[1]
    # A non-rigid error (a rigid shift would be absorbed by that image's pose).
    noise = np.random.default_rng(0).normal(0, 3.0, bad.image_points.shape).astype(np.float32)
    shifted = type(bad)(bad.image_points + noise, bad.object_points, bad.ids)
    cal = calibrate_intrinsics([*views[:1], shifted, *views[2:]], (CAMERA.width, CAMERA.height))
    assert 1 in cal.rejected
    assert "outlier" in cal.rejected[1]
    assert cal.rms_px < 0.1


def test_grazing_board_and_too_few_views():
    grazing = _render(*_board_pose(0, 80.0))
    assert detect_charuco(grazing, SPEC) is None  # too few corners to trust
    with pytest.raises(CameraCalibrationError, match="usable board image"):
        calibrate_intrinsics([None, None, None], (CAMERA.width, CAMERA.height))
    with pytest.raises(ValueError, match="unknown ArUco dictionary"):
        CharucoTarget(dictionary="DICT_NOPE")
