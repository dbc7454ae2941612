"""ArUco markers on the holder plate: where they are, and finding them in a frame.

The layout and corner convention are fixed in ``docs/btf.md``: marker ``i``
carries ArUco id ``i``, is centred at ``holder.marker_centers_mm()[i]`` on the
reference plane z = 0, is axis-aligned and reads upright seen from above
(bitmap row 0 towards +y, column 0 towards −x); its four corners come in
OpenCV's order (top-left, top-right, bottom-right, bottom-left of the bitmap).

References
----------
.. [1] Sattler, Sarlette, Klein. "Efficient and realistic visualization of
   cloth." EGSR 2003, §3.2 (markers on the sample holder plate).
.. [2] Garrido-Jurado et al. "Automatic generation and detection of highly
   reliable fiducial markers under occlusion." Pattern Recognition 47, 2014.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import cv2
import numpy as np

from processing.registration._edges import gray_image, refine_corners
from processing.registration._errors import RegistrationError
from processing.registration._sampling import kernel_frame
from rig.config import Holder

__all__ = ["MarkerDetection", "aruco_dictionary", "detect_markers", "marker_corners_mm"]

# Corner k of a marker relative to its centre, in units of half the side:
# top-left, top-right, bottom-right, bottom-left of the bitmap seen from above.
_CORNER_SIGNS = np.array([[-1.0, 1.0], [1.0, 1.0], [1.0, -1.0], [-1.0, -1.0]])


@functools.lru_cache(maxsize=16)
def marker_corners_mm(holder: Holder) -> np.ndarray:
    """Sample-frame (x, y) in mm of every marker corner on the plate (z = 0).

    Returns
    -------
    (n_markers, 4, 2) float64, read-only
        ``[i, k]`` is corner ``k`` of marker id ``i`` in OpenCV's corner order.
        One array per holder (a frozen config), kept: every frame asks for it.
    """
    centers = np.asarray(holder.marker_centers_mm(), dtype=np.float64)
    corners = centers[:, None, :] + 0.5 * holder.marker_mm * _CORNER_SIGNS[None, :, :]
    corners.setflags(write=False)
    return corners


@functools.lru_cache(maxsize=16)
def aruco_dictionary(holder: Holder) -> cv2.aruco.Dictionary:
    """The OpenCV ArUco dictionary named by ``holder.aruco_dictionary`` (one per holder)."""
    name = holder.aruco_dictionary
    code = getattr(cv2.aruco, name, None) if name.startswith("DICT_") else None
    if not isinstance(code, int):
        valid = sorted(n for n in dir(cv2.aruco) if n.startswith("DICT_"))
        raise RegistrationError(
            f"holder.aruco_dictionary = {name!r} is not an OpenCV ArUco dictionary; "
            f"valid names include {valid[:6]}…"
        )
    dictionary = cv2.aruco.getPredefinedDictionary(code)
    n = len(marker_corners_mm(holder))
    if dictionary.bytesList.shape[0] < n:
        raise RegistrationError(
            f"holder.aruco_dictionary = {name!r} has {dictionary.bytesList.shape[0]} ids "
            f"but the holder needs {n} markers; choose a larger dictionary"
        )
    return dictionary


@dataclass(frozen=True)
class MarkerDetection:
    """The holder markers found in one frame.

    Attributes
    ----------
    ids : (m,) int64
        Marker ids, ascending, each at most once, all valid for the holder.
    corners_px : (m, 4, 2) float64
        Sub-pixel image corners (x = column, y = row, pixel centres at integers)
        in OpenCV's corner order, matching ``marker_corners_mm(holder)[ids]``.
    rejected_ids : (r,) int64
        Ids that were found but dropped: not on this holder, or seen twice.
    """

    ids: np.ndarray
    corners_px: np.ndarray
    rejected_ids: np.ndarray

    def __len__(self) -> int:
        return len(self.ids)


def to_gray(frame: np.ndarray) -> np.ndarray:
    """(H, W) float64 grey level of an (H, W), (H, W, 1) or (H, W, 3) frame; NaN, ±inf → 0.

    The channel mean, summed in channel order ((r + g) + b) / 3.
    """
    image = np.asarray(frame)
    if not np.issubdtype(image.dtype, np.number) or np.iscomplexobj(image):
        raise RegistrationError(f"frame: expected a real-valued image, got dtype {image.dtype}")
    if image.ndim == 2:
        image = image[:, :, None]
    if image.ndim != 3 or image.shape[2] not in (1, 3) or min(image.shape[:2]) < 8:
        raise RegistrationError(
            f"frame: expected an (H, W), (H, W, 1) or (H, W, 3) image at least 8 px "
            f"on a side, got shape {np.shape(frame)}"
        )
    return gray_image(kernel_frame(image))


def to_gray8(gray: np.ndarray) -> np.ndarray:
    """An 8-bit copy of a grey image for the detector, contrast stretched.

    The 0.5 and 99.5 percentiles map to 0 and 255, so dim or high-bit-depth
    frames detect as well as 8-bit ones.
    """
    lo, hi = np.percentile(gray, [0.5, 99.5])
    if hi <= lo:
        return np.zeros(gray.shape, np.uint8)
    return np.clip(np.rint((gray - lo) * (255.0 / (hi - lo))), 0, 255).astype(np.uint8)


def detect_markers(
    frame: np.ndarray, holder: Holder, *, refine_win_px: int = 4, edge_refine: bool = True
) -> MarkerDetection:
    """Find the holder's ArUco markers in ``frame``, corners refined sub-pixel.

    OpenCV's detector finds the markers and refines their corners with
    ``cornerSubPix``; then (``edge_refine``) each corner is replaced by the
    intersection of straight-line fits to the marker's outer edges, which
    removes the ~0.2 px outward bias of ``cornerSubPix`` on convex corners.

    Parameters
    ----------
    frame : (H, W) or (H, W, 3) array, any real dtype
        The raw camera frame (not undistorted).
    holder : rig.config.Holder
        Dictionary name and number of markers.
    refine_win_px : int
        Half-size of the sub-pixel corner refinement window (OpenCV's
        ``cornerRefinementWinSize``); keep it below one marker module.
    edge_refine : bool
        Refine corners by edge-line fits (markers where that fails keep
        OpenCV's corners).

    Returns
    -------
    MarkerDetection
        Possibly empty: finding no marker is a result, not an error.
    """
    if refine_win_px < 1:
        raise RegistrationError(f"refine_win_px = {refine_win_px}: must be ≥ 1")
    gray = to_gray(frame)
    params = cv2.aruco.DetectorParameters()
    params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
    params.cornerRefinementWinSize = int(refine_win_px)
    params.cornerRefinementMaxIterations = 100
    params.cornerRefinementMinAccuracy = 0.001
    dictionary = aruco_dictionary(holder)
    detector = cv2.aruco.ArucoDetector(dictionary, params)
    corners, ids, _ = detector.detectMarkers(to_gray8(gray))
    n_markers = len(marker_corners_mm(holder))
    if ids is None or len(ids) == 0:
        empty = np.zeros(0, np.int64)
        return MarkerDetection(empty, np.zeros((0, 4, 2)), empty)
    found = np.asarray(ids, dtype=np.int64).ravel()
    quads = np.asarray(corners, dtype=np.float64).reshape(-1, 4, 2)
    unique, counts = np.unique(found, return_counts=True)
    keep_ids = unique[(counts == 1) & (unique < n_markers)]
    rejected = np.setdiff1d(unique, keep_ids)
    order = np.argsort(found, kind="stable")
    found, quads = found[order], quads[order]
    keep = np.isin(found, keep_ids)
    found, quads = found[keep], quads[keep]
    if edge_refine:
        quads = refine_corners(gray, quads, modules=dictionary.markerSize + 2)
    return MarkerDetection(found, quads, rejected)
