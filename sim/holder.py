"""The holder plate around the sample: plate, recess walls and floor, markers.

The plate's top is the reference plane z = 0; the sample sits in a square
recess of side ``recess_mm`` (the measured square ``holder.sample_mm`` and a margin
around it, so the walls stay out of the texel grid) and depth ``depth_mm``. ArUco markers are
printed on the plate as an albedo texture, laid out as ``docs/btf.md`` fixes:
marker *i* carries id *i*, is centred at ``holder.marker_centers_mm()[i]``,
measures ``holder.marker_mm`` over its black border, and reads upright when the
plate is seen from above (bitmap row 0 towards +y, column 0 towards −x).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from rig.config import Holder
from rig.errors import ConfigError
from sim.samples import SampleGeometry

__all__ = ["PART_PLATE", "PART_RECESS", "PART_SAMPLE", "SceneMesh", "assemble", "plate_albedo"]

PART_PLATE, PART_RECESS, PART_SAMPLE = 0, 1, 2
PLATE_WHITE = 0.85
MARKER_BLACK = 0.03
RECESS_GREY = 0.5


@dataclass(frozen=True)
class SceneMesh:
    """Everything the cameras can see, one mesh in the sample frame (mm).

    vertices (V, 3) float64, faces (F, 3) int64, normals (V, 3) float64 unit,
    face_material (F,) int64 (0 plate, 1 recess, 2 + k the sample's k-th
    material), face_part (F,) int8 (``PART_*``).
    """

    vertices: np.ndarray
    faces: np.ndarray
    normals: np.ndarray
    face_material: np.ndarray
    face_part: np.ndarray


def _quad(corners: np.ndarray, normal) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    faces = np.array([[0, 1, 2], [0, 2, 3]])
    return corners, np.tile(np.asarray(normal, float), (4, 1)), faces


def assemble(
    holder: Holder, sample: SampleGeometry, *, depth_mm: float, recess_mm: float
) -> SceneMesh:
    """Plate + recess walls (+ floor for non-height-field samples) + the sample.

    ``recess_mm`` (≥ ``holder.sample_mm``) must leave the markers on the plate."""
    P, s, d = holder.plate_mm / 2, recess_mm / 2, depth_mm
    clear = float(np.abs(holder.marker_centers_mm()).max(axis=1).min()) - holder.marker_mm / 2
    if not holder.sample_mm <= recess_mm <= 2 * clear:
        raise ConfigError(
            f"sample.margin_mm: the recess of {recess_mm:g} mm must hold the "
            f"{holder.sample_mm:g} mm measured square and leave the markers, which start "
            f"{clear:g} mm from the centre: a margin of 0 … {clear - holder.sample_mm / 2:g} mm"
        )
    quads = [  # (corners, normal, part)
        ([[-P, s, 0], [P, s, 0], [P, P, 0], [-P, P, 0]], (0, 0, 1), PART_PLATE),
        ([[-P, -P, 0], [P, -P, 0], [P, -s, 0], [-P, -s, 0]], (0, 0, 1), PART_PLATE),
        ([[-P, -s, 0], [-s, -s, 0], [-s, s, 0], [-P, s, 0]], (0, 0, 1), PART_PLATE),
        ([[s, -s, 0], [P, -s, 0], [P, s, 0], [s, s, 0]], (0, 0, 1), PART_PLATE),
        ([[-s, -s, 0], [-s, s, 0], [-s, s, -d], [-s, -s, -d]], (1, 0, 0), PART_RECESS),
        ([[s, -s, 0], [s, -s, -d], [s, s, -d], [s, s, 0]], (-1, 0, 0), PART_RECESS),
        ([[-s, -s, 0], [-s, -s, -d], [s, -s, -d], [s, -s, 0]], (0, 1, 0), PART_RECESS),
        ([[-s, s, 0], [s, s, 0], [s, s, -d], [-s, s, -d]], (0, -1, 0), PART_RECESS),
    ]
    if sample.height is None:
        quads.append(([[-s, -s, -d], [s, -s, -d], [s, s, -d], [-s, s, -d]], (0, 0, 1), PART_RECESS))
    verts, norms, faces, mats, parts = [], [], [], [], []
    count = 0
    for corners, normal, part in quads:
        v, n, f = _quad(np.asarray(corners, float), normal)
        verts.append(v)
        norms.append(n)
        faces.append(f + count)
        mats.append(np.full(2, part))
        parts.append(np.full(2, part))
        count += 4
    verts.append(sample.vertices)
    norms.append(sample.normals)
    faces.append(sample.faces + count)
    mats.append(sample.face_material + 2)
    parts.append(np.full(len(sample.faces), PART_SAMPLE))
    return SceneMesh(
        vertices=np.concatenate(verts).astype(np.float64),
        faces=np.concatenate(faces).astype(np.int64),
        normals=np.concatenate(norms).astype(np.float64),
        face_material=np.concatenate(mats).astype(np.int64),
        face_part=np.concatenate(parts).astype(np.int8),
    )


def _marker_bits(holder: Holder) -> list[np.ndarray]:
    name = holder.aruco_dictionary
    code = getattr(cv2.aruco, name, None)
    if not name.startswith("DICT_") or code is None:
        raise ConfigError(f"holder.aruco_dictionary: unknown ArUco dictionary {name!r}")
    dictionary = cv2.aruco.getPredefinedDictionary(code)
    n = len(holder.marker_centers_mm())
    if n > dictionary.bytesList.shape[0]:
        raise ConfigError(
            f"holder.markers_per_side: {n} markers exceed the {dictionary.bytesList.shape[0]} "
            f"ids of {name}"
        )
    modules = dictionary.markerSize + 2  # one module of black border each side
    return [
        cv2.aruco.generateImageMarker(dictionary, i, modules, borderBits=1) > 127 for i in range(n)
    ]


def plate_albedo(holder: Holder):
    """A function ``xy (n, 2) mm -> albedo (n, 3)`` of the plate with its markers.

    Each marker module is looked up exactly (no resampling): white plate
    ``PLATE_WHITE``, black modules ``MARKER_BLACK``.
    """
    bits = _marker_bits(holder)
    centres = holder.marker_centers_mm()
    side = holder.marker_mm

    def albedo(xy: np.ndarray) -> np.ndarray:
        value = np.full(len(xy), PLATE_WHITE)
        for (cx, cy), bitmap in zip(centres, bits, strict=True):
            m = bitmap.shape[0]
            u = (xy[:, 0] - (cx - side / 2)) / side  # 0 at the left (−x) edge
            v = ((cy + side / 2) - xy[:, 1]) / side  # 0 at the top (+y) edge
            inside = (u >= 0) & (u < 1) & (v >= 0) & (v < 1)
            if not inside.any():
                continue
            col = np.minimum((u[inside] * m).astype(np.int64), m - 1)
            row = np.minimum((v[inside] * m).astype(np.int64), m - 1)
            value[inside] = np.where(bitmap[row, col], PLATE_WHITE, MARKER_BLACK)
        return np.repeat(value[:, None], 3, axis=1)

    return albedo
