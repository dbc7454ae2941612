"""The homography from a frame to the reference plane, fitted to marker corners.

Every marker corner found gives one correspondence between its (undistorted)
image position and its known position on the plate (mm, z = 0). The fit is a
normalised DLT [1]_ refined by Gauss–Newton on the reprojection error in the
image (one compiled call, :mod:`._gauss_newton`), with markers whose corners
disagree by more than ``outlier_px`` dropped and the fit repeated.
Before a frame may be warped, the fit's conditioning is checked: how much
corner noise it would amplify at the corners of the sample square.

References
----------
.. [1] Hartley, Zisserman. *Multiple View Geometry*, 2nd ed., §4.4 (normalised
   DLT) and §5.2 (covariance of an estimated homography).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from processing.registration._errors import Reason, RegistrationError
from processing.registration._gauss_newton import fit_homography, noise_gain
from processing.registration._markers import MarkerDetection, marker_corners_mm
from rig.camera import PinholeCamera
from rig.config import Holder

__all__ = ["PlaneHomography", "fit_plane_homography", "pose_plane_homography", "undistort_px"]


@dataclass(frozen=True)
class PlaneHomography:
    """A frame's homography to the reference plane and how well it fits.

    Attributes
    ----------
    plane_to_image : (3, 3) float64
        Maps homogeneous sample-frame plate points (x_mm, y_mm, 1) to
        undistorted pixels (x = column, y = row); zeros when not ``valid``.
    image_to_plane : (3, 3) float64
        Its inverse (undistorted pixels → mm); zeros when not ``valid``.
    valid : bool
        True when ``reason`` is ``Reason.OK`` (from the markers) or
        ``Reason.FROM_RIG_POSE`` (from the posed camera model): the frame may
        be warped.
    reason : Reason
        The first check that failed.
    ids : (m,) int64
        Markers used in the fit (outliers removed).
    reprojection_px : (m,) float64
        RMS reprojection error of each used marker's corners, in raw frame
        pixels (distortion applied); zeros when no fit was made.
    mean_reprojection_px : float
        Mean over all used corners of the reprojection distance (px).
    noise_gain : float
        Predicted RMS image-position error at the sample corners per pixel of
        independent corner noise (≤ 1 means the fit averages noise down);
        ``inf`` is never stored — a degenerate fit reports ``1e12``.
    outlier_ids : (k,) int64
        Markers dropped as outliers.
    """

    plane_to_image: np.ndarray
    image_to_plane: np.ndarray
    valid: bool
    reason: Reason
    ids: np.ndarray
    reprojection_px: np.ndarray
    mean_reprojection_px: float
    noise_gain: float
    outlier_ids: np.ndarray


def undistort_px(pixels: np.ndarray, camera: PinholeCamera | None) -> np.ndarray:
    """Undistorted pixel positions of raw ``pixels`` (n, 2); unchanged without a camera."""
    pix = np.asarray(pixels, dtype=np.float64).reshape(-1, 2)
    if camera is None or not np.any(camera.dist) or len(pix) == 0:
        return pix
    und = cv2.undistortPoints(
        pix.reshape(-1, 1, 2),
        camera.K,
        camera.dist,
        P=camera.K,
        criteria=(cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-12),
    )
    return und.reshape(-1, 2).astype(np.float64)


def distort_px(pixels: np.ndarray, camera: PinholeCamera | None) -> np.ndarray:
    """Raw pixel positions of undistorted ``pixels`` (n, 2) through the lens model."""
    pix = np.asarray(pixels, dtype=np.float64).reshape(-1, 2)
    if camera is None or not np.any(camera.dist) or len(pix) == 0:
        return pix
    K = camera.K
    normalised = np.linalg.solve(K[:2, :2], (pix - K[:2, 2]).T).T
    rays = np.column_stack([normalised, np.ones(len(pix))])
    raw, _ = cv2.projectPoints(rays, np.zeros(3), np.zeros(3), K, camera.dist)
    return raw.reshape(-1, 2).astype(np.float64)


def _apply(H: np.ndarray, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Map (n, 2) points through H; returns the points and the homogeneous w.

    Written out per coordinate: an (n, 3) @ (3, 3) product goes through BLAS, whose
    threads cost several times the arithmetic on a shared machine.
    """
    x, y = points[:, 0], points[:, 1]
    w = H[2, 0] * x + H[2, 1] * y + H[2, 2]
    safe = np.where(np.abs(w) < 1e-300, 1e-300, w)
    out = np.empty((len(points), 2))
    out[:, 0] = (H[0, 0] * x + H[0, 1] * y + H[0, 2]) / safe
    out[:, 1] = (H[1, 0] * x + H[1, 1] * y + H[1, 2]) / safe
    return out, w


def fit_plane_homography(
    detection: MarkerDetection,
    holder: Holder,
    *,
    camera: PinholeCamera | None = None,
    min_markers: int = 3,
    min_spread: float = 0.02,
    max_noise_gain: float = 2.0,
    outlier_px: float = 2.0,
    max_reprojection_px: float = 1.0,
) -> PlaneHomography:
    """Fit the homography between a frame and the reference plane from its markers.

    Parameters
    ----------
    detection : MarkerDetection
        Markers found in the raw frame (:func:`detect_markers`).
    holder : rig.config.Holder
        Plate layout: marker positions and the sample square.
    camera : PinholeCamera, optional
        Lens model; corners are undistorted with ``camera.K`` and
        ``camera.dist`` before the fit (its pose is not used).
    min_markers : int
        Fewer markers than this → ``Reason.TOO_FEW_MARKERS``.
    min_spread : float
        Smallest allowed ratio of the minor to the major standard deviation
        of the used plate points; below it → ``Reason.COLLINEAR_MARKERS``.
    max_noise_gain : float
        Largest allowed :attr:`PlaneHomography.noise_gain`; above it →
        ``Reason.ILL_CONDITIONED``.
    outlier_px : float
        While the worst marker's RMS corner error exceeds this, it is dropped
        and the fit repeated (down to ``min_markers``).
    max_reprojection_px : float
        Mean reprojection error above this → ``Reason.HIGH_REPROJECTION``.

    Returns
    -------
    PlaneHomography
        Always returned; check ``valid`` before warping.
    """
    if min_markers < 1:
        raise RegistrationError(f"min_markers = {min_markers}: must be ≥ 1")
    limits = {
        "min_spread": min_spread,
        "max_noise_gain": max_noise_gain,
        "outlier_px": outlier_px,
        "max_reprojection_px": max_reprojection_px,
    }
    for name, value in limits.items():
        if not np.isfinite(value) or value <= 0:
            raise RegistrationError(f"{name} = {value}: must be a finite number > 0")
    ids = np.asarray(detection.ids, dtype=np.int64)
    n_known = len(marker_corners_mm(holder))
    if ids.size and (ids.min() < 0 or ids.max() >= n_known):
        raise RegistrationError(
            f"detection.ids {ids.tolist()} include ids outside 0…{n_known - 1} of this holder"
        )
    empty = np.zeros(0, np.int64)

    def flagged(reason: Reason, used=empty, errors=None, mean=0.0, gain=0.0, outliers=empty):
        errors = np.zeros(len(used)) if errors is None else errors
        zero = np.zeros((3, 3))
        return PlaneHomography(zero, zero, False, reason, used, errors, mean, gain, outliers)

    if len(ids) < min_markers:
        return flagged(Reason.TOO_FEW_MARKERS, ids)
    all_plane = marker_corners_mm(holder)
    raw = np.asarray(detection.corners_px, dtype=np.float64).reshape(-1, 4, 2)
    if not np.all(np.isfinite(raw)):
        raise RegistrationError("detection.corners_px contains NaN or inf")
    image_all = undistort_px(raw.reshape(-1, 2), camera).reshape(-1, 4, 2)

    # Drop the worst marker while it is off by more than outlier_px, one at a
    # time: a gross outlier drags the least-squares fit, so its neighbours'
    # errors only fall back under the limit once it is gone.
    keep = np.ones(len(ids), bool)
    while True:
        plane = all_plane[ids[keep]].reshape(-1, 2)
        centred = plane - plane.mean(axis=0)
        spread = np.linalg.svd(centred, compute_uv=False)
        if spread[1] < min_spread * spread[0]:
            return flagged(Reason.COLLINEAR_MARKERS, ids[keep], outliers=ids[~keep])
        image = image_all[keep].reshape(-1, 2)
        H = fit_homography(plane, image)
        projected = _apply(H, plane)
        pred = projected[0]
        rms = np.sqrt(np.mean(np.sum((pred - image) ** 2, axis=1).reshape(-1, 4), axis=1))
        if rms.max() <= outlier_px or keep.sum() <= min_markers:
            break
        keep[np.flatnonzero(keep)[np.argmax(rms)]] = False

    used, outliers = ids[keep], ids[~keep]  # plane and projected are the last fit's
    predicted = distort_px(pred, camera)
    distance = np.linalg.norm(predicted - raw[keep].reshape(-1, 2), axis=1)
    per_marker = np.sqrt(np.mean(distance.reshape(-1, 4) ** 2, axis=1))
    mean_err = float(np.mean(distance))
    half = holder.sample_mm / 2
    sample_corners = np.array([[-half, half], [half, half], [half, -half], [-half, -half]])
    gain = noise_gain(H, plane, sample_corners)
    w_plate = projected[1]
    _, w_sample = _apply(H, sample_corners)
    # All plate points, markers and sample alike, must lie on one side of the
    # camera: w changes sign across the horizon line of the plane.
    if not (np.all(w_sample * np.sign(w_plate[0]) > 0)):
        return flagged(Reason.SAMPLE_NOT_VISIBLE, used, per_marker, mean_err, gain, outliers)
    if gain > max_noise_gain:
        return flagged(Reason.ILL_CONDITIONED, used, per_marker, mean_err, gain, outliers)
    if mean_err > max_reprojection_px:
        return flagged(Reason.HIGH_REPROJECTION, used, per_marker, mean_err, gain, outliers)
    H = H / H[2, 2] if abs(H[2, 2]) > 1e-12 * np.abs(H).max() else H
    inverse = np.linalg.inv(H)
    return PlaneHomography(H, inverse, True, Reason.OK, used, per_marker, mean_err, gain, outliers)


def pose_plane_homography(posed: PinholeCamera, holder: Holder) -> PlaneHomography:
    """The plate-plane homography a posed camera model gives, without markers.

    The plate plane is z = 0 of the sample frame, so a plate point (x, y)
    maps to undistorted pixels by ``K [r1 r2 t] (x, y, 1)``, with ``r1, r2``
    the first two columns of the world→camera rotation [1]_ §8.1.1.

    Parameters
    ----------
    posed : PinholeCamera
        Lens and pose in the sample frame (mm), e.g. from the arm's reported
        tool pose and the rail (``rig.bonn.camera_model``).
    holder : rig.config.Holder
        Its ``sample_mm`` gives the sample square that must be in view.

    Returns
    -------
    PlaneHomography
        ``reason`` ``Reason.FROM_RIG_POSE`` (valid) with no markers, no
        reprojection error and ``noise_gain`` 0; ``Reason.SAMPLE_NOT_VISIBLE``
        when a sample corner lies at or behind the camera plane.
    """
    H = posed.K @ np.column_stack([posed.R[:, 0], posed.R[:, 1], posed.t])
    half = holder.sample_mm / 2
    sample_corners = np.array([[-half, half], [half, half], [half, -half], [-half, -half]])
    _, in_front = posed.project(np.column_stack([sample_corners, np.zeros(4)]))
    empty, zero = np.zeros(0, np.int64), np.zeros((3, 3))
    if not np.all(in_front):
        reason = Reason.SAMPLE_NOT_VISIBLE
        return PlaneHomography(zero, zero, False, reason, empty, np.zeros(0), 0.0, 0.0, empty)
    H = H / H[2, 2]  # t_z > 0 when the sample centre is in front
    inverse = np.linalg.inv(H)
    reason = Reason.FROM_RIG_POSE
    return PlaneHomography(H, inverse, True, reason, empty, np.zeros(0), 0.0, 0.0, empty)
