"""Calibration targets as samples: the ChArUco wedge and the laser step block.

Their parameters are the rig's own target specs (:mod:`rig.targets`), so the
simulator renders exactly the part that calibration measures with. Both rise
above the reference plane (a target stands on the holder), which a sample may
not.
"""

from __future__ import annotations

from functools import lru_cache

import cv2
import numpy as np
from scipy.ndimage import map_coordinates

from rig.errors import ConfigError
from rig.targets import CharucoTarget, LaserStepTarget
from sim.samples.base import SampleGeometry, height_field_geometry, register_sample

__all__ = ["BOARD_BLACK", "board_pattern"]

BOARD_BLACK = 0.04  # reflectance of the print relative to the white board
PRINT_DOT_MM = 0.15  # the print's resolution (~170 dpi): edges are a box this wide
_PX_PER_MM = 20  # board bitmap resolution: squares and markers fall on whole pixels


@lru_cache(maxsize=4)
def _board_image(board: CharucoTarget) -> np.ndarray:
    w, h = board.size_mm
    size = (round(w * _PX_PER_MM), round(h * _PX_PER_MM))
    bitmap = board.board().generateImage(size, marginSize=0, borderBits=1) > 127
    image = np.where(bitmap, 1.0, BOARD_BLACK).astype(np.float32)
    dot = 2 * round(PRINT_DOT_MM * _PX_PER_MM / 2) + 1  # odd: centred, no shift
    return cv2.blur(image, (dot, dot), borderType=cv2.BORDER_REPLICATE)


def board_pattern(board: CharucoTarget):
    """``points (n, 3) -> (n,)``: the printed board's reflectance factor (1 on
    white, ``BOARD_BLACK`` on black, 1 off the board), its edges as wide as one
    print dot. Without that width a regular supersampling grid quantises edges
    that run along the pixel rows, which biases corner positions by up to
    1/(2k) px; a real sensor integrates its pixel's area exactly."""
    image = _board_image(board)
    R, t = board.board_pose()
    rows, cols = image.shape

    def pattern(points: np.ndarray) -> np.ndarray:
        b = (np.asarray(points, dtype=np.float64) - t) @ R  # board coordinates, mm
        col, row = b[:, 0] * _PX_PER_MM - 0.5, b[:, 1] * _PX_PER_MM - 0.5
        inside = (b[:, 0] >= 0) & (col < cols) & (b[:, 1] >= 0) & (row < rows)
        out = np.ones(len(b))
        out[inside] = map_coordinates(image, [row[inside], col[inside]], order=1, mode="nearest")
        return out

    return pattern


@register_sample("charuco_wedge", CharucoTarget)
def _charuco_wedge(board: CharucoTarget, *, sample_mm: float, depth_mm: float) -> SampleGeometry:
    w, h = board.size_mm
    if w * np.cos(np.deg2rad(board.tilt_deg)) > sample_mm + 1e-9 or h > sample_mm + 1e-9:
        raise ConfigError(
            f"targets.charuco: the board ({w:g} × {h:g} mm at {board.tilt_deg:g}°) does not fit "
            f"the {sample_mm:g} mm sample area; use fewer or smaller squares or a steeper wedge"
        )
    R, t = board.board_pose()
    normal = R[:, 2]  # board z: into the wedge
    # The plane through t with that normal: n·(p − t) = 0, solved for z.

    def h(x, y):
        x = np.asarray(x, dtype=np.float64)
        return t[2] - (normal[0] * (x - t[0]) + normal[1] * (np.asarray(y) - t[1])) / normal[2]

    top = float(max(h(np.array([-sample_mm / 2, sample_mm / 2]), np.zeros(2))))
    geometry = height_field_geometry(h, sample_mm=sample_mm, grid=2, depth_mm=depth_mm, top_mm=top)
    return SampleGeometry(
        geometry.vertices, geometry.faces, geometry.normals, geometry.face_material,
        height=h, pattern=board_pattern(board),
    )  # fmt: skip


@register_sample("laser_steps", LaserStepTarget)
def _laser_steps(steps: LaserStepTarget, *, sample_mm: float, depth_mm: float) -> SampleGeometry:
    """Flat bands along x, band i over y ∈ [edge_i, edge_i+1] at heights_mm[i],
    joined by vertical walls and closed down to the recess floor at the sides."""
    s = sample_mm / 2
    edges = steps.band_edges_mm(sample_mm)
    heights = np.asarray(steps.heights_mm, dtype=np.float64)
    quads = []  # (corners counter-clockwise seen from outside, normal)
    for y0, y1, z in zip(edges[:-1], edges[1:], heights, strict=True):
        quads.append(([[-s, y0, z], [s, y0, z], [s, y1, z], [-s, y1, z]], (0, 0, 1)))
        quads.append(([[-s, y0, -depth_mm], [-s, y0, z], [-s, y1, z], [-s, y1, -depth_mm]],
                      (-1, 0, 0)))  # fmt: skip
        quads.append(([[s, y0, -depth_mm], [s, y1, -depth_mm], [s, y1, z], [s, y0, z]], (1, 0, 0)))
    bounds = np.concatenate([[-depth_mm], heights, [-depth_mm]])
    for y, below, above in zip(edges, bounds[:-1], bounds[1:], strict=True):
        lo, hi = sorted((below, above))
        normal = (0, -1, 0) if above > below else (0, 1, 0)
        quads.append(([[-s, y, lo], [s, y, lo], [s, y, hi], [-s, y, hi]], normal))
    verts, norms, faces = [], [], []
    for k, (corners, normal) in enumerate(quads):
        c = np.asarray(corners, dtype=np.float64)
        n = np.asarray(normal, dtype=np.float64)
        if np.cross(c[1] - c[0], c[2] - c[0]) @ n < 0:
            c = c[::-1]
        verts.append(c)
        norms.append(np.tile(n, (4, 1)))
        faces.append(np.array([[0, 1, 2], [0, 2, 3]]) + 4 * k)
    faces = np.concatenate(faces).astype(np.int64)
    return SampleGeometry(
        vertices=np.concatenate(verts), faces=faces, normals=np.concatenate(norms),
        face_material=np.zeros(len(faces), dtype=np.int64),
    )  # fmt: skip
