"""Markers found where the rig's pose says they are, without the ArUco detector.

The rig records where it stood for every frame, so the camera model posed in
the sample frame says where each marker's corners should appear. From there
the edge fits of :mod:`._edges` locate the corners directly, and the marker's
bits, read through its refined corners, confirm that the right marker was
found. OpenCV's detector (thresholds, contours and candidate decoding over the
whole frame) took a third of a frame's registration; reading the bits takes a
twentieth of that, the edge fits both ways run are what is left.
A marker misplaced by the expectation fails its edge fits or its bits and is
left out; when too few remain, the caller runs the detector (:func:`register_frame`).
"""

from __future__ import annotations

import functools

import cv2
import numpy as np

from processing.registration._edges import fit_corners, sample_gray
from processing.registration._errors import RegistrationError
from processing.registration._markers import (
    MarkerDetection,
    aruco_dictionary,
    marker_corners_mm,
    to_gray,
)
from rig.camera import PinholeCamera
from rig.config import Holder

__all__ = ["expected_corners_px", "track_markers"]


def expected_corners_px(posed: PinholeCamera, holder: Holder) -> np.ndarray:
    """Raw pixel positions (n_markers, 4, 2) of every marker corner through ``posed``.

    ``posed`` is the camera model (lens included) in the sample frame, mm; a
    marker with a corner at or behind the camera plane is NaN.
    """
    plate = marker_corners_mm(holder)
    points = np.column_stack([plate.reshape(-1, 2), np.zeros(plate.shape[0] * 4)])
    pixels, in_front = posed.project(points)
    pixels = pixels.reshape(-1, 4, 2)
    pixels[~in_front.reshape(-1, 4).all(axis=1)] = np.nan
    return pixels


def track_markers(frame: np.ndarray, holder: Holder, expected_px: np.ndarray) -> MarkerDetection:
    """The holder's markers, refined from their expected corners and checked by their bits.

    A marker is looked for where all four expected corners lie in the frame.

    Parameters
    ----------
    frame : (H, W) or (H, W, C) array, any real dtype
        The raw frame.
    holder : rig.config.Holder
        Dictionary and layout.
    expected_px : (n_markers, 4, 2) float64
        Expected raw corners (x = column, y = row) in OpenCV's order, good to
        about a third of a module (the edge fits look 0.8 of a module either
        side); NaN rows are skipped.

    Returns
    -------
    MarkerDetection
        The markers whose four edges were located and whose bits read as
        their id; none rejected (a marker is only ever looked for as itself).
    """
    gray = to_gray(frame)
    dictionary = aruco_dictionary(holder)
    n_markers = len(marker_corners_mm(holder))
    expected = np.asarray(expected_px, dtype=np.float64)
    if expected.shape != (n_markers, 4, 2):
        raise RegistrationError(
            f"expected_px: expected shape ({n_markers}, 4, 2) for the holder's markers, "
            f"got {expected.shape}"
        )
    bits = dictionary.markerSize
    modules = bits + 2
    height, width = gray.shape
    # Every corner inside the frame, as the detector needs them; beyond the frame's edge
    # the edge normals and the quiet ring read the edge pixels, and a marker the edge
    # cuts fails its edges or its bits.
    with np.errstate(invalid="ignore"):
        inside = (
            (expected[:, :, 0] >= 0) & (expected[:, :, 0] <= width - 1)
            & (expected[:, :, 1] >= 0) & (expected[:, :, 1] <= height - 1)
        ).all(axis=1)  # fmt: skip
    candidates = np.flatnonzero(inside)
    quads, ok = fit_corners(gray, expected[candidates], modules=modules)
    ids, quads = candidates[ok], quads[ok]
    reads = _reads_as(gray, quads, _marker_bits(holder)[ids], modules)
    return MarkerDetection(ids[reads], quads[reads], np.zeros(0, np.int64))


@functools.lru_cache(maxsize=16)
def _marker_bits(holder: Holder) -> np.ndarray:
    """(n_markers, bits, bits) bool: True where a marker's module is white, row 0 on top."""
    dictionary = aruco_dictionary(holder)
    size = dictionary.markerSize
    bits = [cv2.aruco.Dictionary.getBitsFromByteList(dictionary.bytesList[i : i + 1], size)
            for i in range(len(marker_corners_mm(holder)))]  # fmt: skip
    bits = np.asarray(bits, dtype=bool).reshape(-1, size, size)
    bits.setflags(write=False)
    return bits


def _square_to_quads(quads: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Points (m, k, 2) of the unit square's ``uv`` (k, 2) mapped onto each quad (m, 4, 2).

    The projective map taking (0, 0), (1, 0), (1, 1), (0, 1) to the quad's corners,
    in closed form (Heckbert 1989, §2.2.3), for all quads at once.
    """
    p0, p1, p2, p3 = (quads[:, k] for k in range(4))
    s = p0 - p1 + p2 - p3
    d1, d2 = p1 - p2, p3 - p2
    den = d1[:, 0] * d2[:, 1] - d2[:, 0] * d1[:, 1]
    g = (s[:, 0] * d2[:, 1] - d2[:, 0] * s[:, 1]) / den
    h = (d1[:, 0] * s[:, 1] - s[:, 0] * d1[:, 1]) / den
    a = p1 - p0 + g[:, None] * p1  # (m, 2): the u column
    b = p3 - p0 + h[:, None] * p3  # the v column
    u, v = uv[None, :, 0:1], uv[None, :, 1:2]
    w = g[:, None, None] * u + h[:, None, None] * v + 1.0
    return (a[:, None, :] * u + b[:, None, :] * v + p0[:, None, :]) / w


def _reads_as(gray: np.ndarray, quads: np.ndarray, bits: np.ndarray, modules: int) -> np.ndarray:
    """(m,) bool: whether each marker (corners ``quads`` (m, 4, 2)) shows its ``bits``
    (m, b, b) inside an all-black border.

    Every module's centre is read through the quad's homography; each marker's
    threshold lies halfway between its border ring (black) and the ring of plate
    one module outside it.
    """
    m = len(quads)
    if m == 0:
        return np.zeros(0, bool)
    cells = (np.arange(-1, modules + 1) + 0.5) / modules  # quiet ring, border, bits
    u, v = np.meshgrid(cells, cells)
    points = _square_to_quads(quads, np.column_stack([u.ravel(), v.ravel()]))
    n = modules + 2
    levels = sample_gray(gray, points).reshape(m, n, n)
    quiet = np.median(levels[:, _ring(n)], axis=1)
    border = levels[:, 1:-1, 1:-1][:, _ring(n - 2)]
    threshold = 0.5 * (quiet + np.median(border, axis=1))
    inner = levels[:, 2:-2, 2:-2] > threshold[:, None, None]
    return (
        (quiet > threshold)
        & (border < threshold[:, None]).all(axis=1)
        & (inner == bits).all(axis=(1, 2))
    )


def _ring(n: int) -> np.ndarray:
    """(n, n) bool: the outermost cells of an n × n grid."""
    ring = np.ones((n, n), bool)
    ring[1:-1, 1:-1] = False
    return ring
