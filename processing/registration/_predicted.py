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
from numba import njit

from processing._numba_cache import keep_fresh
from processing.registration import _edges
from processing.registration._edges import _bilinear, _median, fit_corners
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


def _reads_as(gray: np.ndarray, quads: np.ndarray, bits: np.ndarray, modules: int) -> np.ndarray:
    """(m,) bool: whether each marker (corners ``quads`` (m, 4, 2)) shows its ``bits``
    (m, b, b) inside an all-black border.

    Every module's centre is read through the quad's homography; each marker's
    threshold lies halfway between its border ring (black) and the ring of plate
    one module outside it.
    """
    reads = np.zeros(len(quads), np.bool_)
    _read_bits(
        np.ascontiguousarray(gray, dtype=np.float64), np.ascontiguousarray(quads, np.float64),
        np.ascontiguousarray(bits), int(modules), reads,
    )  # fmt: skip
    return reads


@njit(cache=True, nogil=True)
def _read_bits(gray, quads, bits, modules, reads):
    """:func:`_reads_as` into ``reads`` (m,), compiled: as numpy calls on a frame's
    sixteen markers it took a twentieth of a registration."""
    n = modules + 2  # the quiet ring, the border and the bits
    levels = np.empty((n, n))
    quiet = np.empty(4 * (n - 1))
    border = np.empty(4 * (n - 3))
    for i in range(quads.shape[0]):
        # The projective map taking the unit square's (0, 0), (1, 0), (1, 1), (0, 1) to
        # the quad's corners, in closed form (Heckbert 1989, §2.2.3).
        p0, p1, p2, p3 = quads[i, 0], quads[i, 1], quads[i, 2], quads[i, 3]
        sx, sy = p0[0] - p1[0] + p2[0] - p3[0], p0[1] - p1[1] + p2[1] - p3[1]
        d1x, d1y, d2x, d2y = p1[0] - p2[0], p1[1] - p2[1], p3[0] - p2[0], p3[1] - p2[1]
        den = d1x * d2y - d2x * d1y
        g = (sx * d2y - d2x * sy) / den
        h = (d1x * sy - sx * d1y) / den
        ax, ay = p1[0] - p0[0] + g * p1[0], p1[1] - p0[1] + g * p1[1]  # the u column
        bx, by = p3[0] - p0[0] + h * p3[0], p3[1] - p0[1] + h * p3[1]  # the v column
        for r in range(n):
            v = (r - 1 + 0.5) / modules
            for c in range(n):
                u = (c - 1 + 0.5) / modules
                w = g * u + h * v + 1.0
                x, y = (ax * u + bx * v + p0[0]) / w, (ay * u + by * v + p0[1]) / w
                levels[r, c] = _bilinear(gray, x, y)
        _ring_of(levels, 0, quiet)
        _ring_of(levels, 1, border)
        # The medians reorder the rings' copies; the border is checked as a set.
        plate = _median(quiet, len(quiet))
        threshold = 0.5 * (plate + _median(border, len(border)))
        ok = plate > threshold
        for k in range(len(border)):
            ok &= border[k] < threshold
        for r in range(n - 4):
            for c in range(n - 4):
                ok &= (levels[r + 2, c + 2] > threshold) == bits[i, r, c]
        reads[i] = ok


@njit(cache=True, nogil=True)
def _ring_of(levels, inset, out):
    """The cells of the ring ``inset`` cells in from the edge of ``levels`` (n, n) into
    ``out`` (4 (n − 2 inset − 1),), in no particular order (the medians and the all-dark
    check do not need one)."""
    lo, hi = inset, levels.shape[0] - 1 - inset
    k = 0
    for c in range(lo, hi + 1):  # the top and bottom rows
        out[k], out[k + 1] = levels[lo, c], levels[hi, c]
        k += 2
    for r in range(lo + 1, hi):  # the sides between them
        out[k], out[k + 1] = levels[r, lo], levels[r, hi]
        k += 2


keep_fresh(__name__, _edges)
