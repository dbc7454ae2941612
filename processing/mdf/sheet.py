"""Laser planes of a scan: from each frame's line on the reference plane, in time.

Seed ``001_…`` section 3.2: the laser plane of a frame contains the laser line
detected on the reference plane and meets the reference plane at the angle
found in calibration ("project the laser strip onto two planes with different
heights"). The seed treats all planes of one scan as parallel (constant angle).
The LEGO unit tilts its emitter, so the sheets really form a pencil through the
emitter and their angle changes over the sweep; both models are offered:

- ``angle_deg`` given (a number, or one per frame): the seed's model;
- ``angle_deg=None``: the plane through the detected line and the emitter at
  ``source_mm`` (exact for a sheet pivoting about its emitter).

Either way the plane rises from the line towards the emitter's side, so the
emitter position is needed (it is also needed for the merge weights).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from processing.mdf._errors import MdfError
from processing.mdf.line import LaserLine, LineReason

__all__ = ["ScanPlanes", "scan_planes", "sheet_from_line", "tetrahedron_weight"]


def sheet_from_line(
    line: LaserLine, *, source_mm, angle_deg: float | None = None
) -> tuple[np.ndarray, float]:
    """The laser plane ``normal · x = offset`` of a frame from its line.

    Parameters
    ----------
    line : LaserLine
        A valid line (``line.valid``).
    source_mm : (3,) float
        Emitter position in the sample frame, mm (z > 0).
    angle_deg : float or None
        Angle between the laser plane and the reference plane, in (0, 90].
        None: the plane through the line and the emitter.

    Returns
    -------
    normal : (3,) float64 unit vector with ``normal[2] >= 0``
    offset : float, mm
    """
    if not line.valid:
        raise MdfError(f"sheet_from_line: the frame has no laser line ({line.reason.name})")
    source = np.asarray(source_mm, dtype=np.float64)
    if source.shape != (3,) or not np.all(np.isfinite(source)) or source[2] <= 0:
        raise MdfError(f"source_mm must be a finite 3-vector above the plate, got {source_mm}")
    m, rho = np.asarray(line.normal, dtype=np.float64), float(line.rho_mm)
    side = float(m @ source[:2] - rho)
    if side < 0:  # orient m towards the emitter's foot
        m, rho, side = -m, -rho, -side
    if angle_deg is None:
        angle = np.arctan2(source[2], side)
    else:
        if not 0 < angle_deg <= 90:
            raise MdfError(f"sheet angle must be in (0, 90] degrees, got {angle_deg}")
        angle = np.deg2rad(angle_deg)
    normal = np.array([-np.sin(angle) * m[0], -np.sin(angle) * m[1], np.cos(angle)])
    return normal, float(-np.sin(angle) * rho)


@dataclass(frozen=True)
class ScanPlanes:
    """The laser plane of every frame of one scan.

    Attributes
    ----------
    normal : (F, 3) float64
        Unit normals (``normal[:, 2] >= 0``); zeros where invalid.
    offset : (F,) float64
        ``normal · x = offset``, mm.
    reason : (F,) uint8
        :class:`~processing.mdf.line.LineReason` per frame; OK ⇔ a plane.
    """

    normal: np.ndarray
    offset: np.ndarray
    reason: np.ndarray

    @property
    def valid(self) -> np.ndarray:
        """(F,) bool: frames with a plane."""
        return self.reason == LineReason.OK

    def at(self, time) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The plane at fractional frame times, interpolated between frames.

        Between two frames the plane equations are blended linearly and
        renormalised: for parallel planes this moves the plane uniformly, for
        a pencil through the emitter it stays in the pencil.

        Parameters
        ----------
        time : (...) float
            Frame index with fraction; both neighbouring frames need a plane
            (one when the time is integral).

        Returns
        -------
        normal : (..., 3) float64
        offset : (...) float64
        ok : (...) bool
            False outside [0, F-1] or where a neighbour has no plane.
        """
        t = np.asarray(time, dtype=np.float64)
        n_frames = len(self.offset)
        inside = np.isfinite(t) & (t >= 0) & (t <= n_frames - 1)
        tc = np.where(inside, t, 0.0)
        i0 = np.minimum(np.floor(tc).astype(np.intp), max(n_frames - 2, 0))
        i1 = np.minimum(i0 + 1, n_frames - 1)
        frac = tc - i0
        valid = self.valid
        both = valid[i0] & valid[i1]
        ok = inside & np.where(frac == 0, valid[i0], np.where(frac == 1, valid[i1], both))
        f = frac[..., None]
        normal = (1 - f) * self.normal[i0] + f * self.normal[i1]
        offset = (1 - frac) * self.offset[i0] + frac * self.offset[i1]
        norm = np.linalg.norm(normal, axis=-1)
        ok &= norm > 0.5
        scale = np.where(ok, norm, 1.0)
        normal = np.where(ok[..., None], normal / scale[..., None], 0.0)
        return normal, np.where(ok, offset / scale, 0.0), ok


def scan_planes(
    lines: Sequence[LaserLine], *, source_mm, angle_deg: float | Sequence[float] | None = None
) -> ScanPlanes:
    """Planes of all frames of a scan from their lines.

    Parameters
    ----------
    lines : F × LaserLine
    source_mm : (3,) float
        Emitter position, sample frame, mm.
    angle_deg : None, float or (F,) float
        See :func:`sheet_from_line`; one angle per frame when the calibration
        gives the angle as a function of the emitter tilt.

    Returns
    -------
    ScanPlanes
    """
    n_frames = len(lines)
    if n_frames == 0:
        raise MdfError("scan_planes: a scan needs at least one frame")
    if angle_deg is None:
        angles = [None] * n_frames
    else:
        angles = np.broadcast_to(np.asarray(angle_deg, dtype=np.float64), (n_frames,)).tolist()
    normal = np.zeros((n_frames, 3))
    offset = np.zeros(n_frames)
    reason = np.array([line.reason for line in lines], dtype=np.uint8)
    for i, line in enumerate(lines):
        if line.valid:
            normal[i], offset[i] = sheet_from_line(line, source_mm=source_mm, angle_deg=angles[i])
    return ScanPlanes(normal=normal, offset=offset, reason=reason)


def tetrahedron_weight(
    source_mm, camera_center_mm, strip_direction, *, half_length_mm: float
) -> float:
    """Merge weight of one laser location for one view (seed section 3.2).

    The volume of the tetrahedron formed by the laser source, the camera
    centre and two points on the laser line through the turntable centre, at
    ``± half_length_mm`` along the strip. It grows with the triangulation
    angle between view rays and laser planes (error analysis of Bouguet and
    Perona's shadow scanning, the seed's [2]).

    Parameters
    ----------
    source_mm, camera_center_mm : (3,) float
        Sample frame, mm.
    strip_direction : (2,) or (3,) float
        Direction of the laser line on the reference plane.
    half_length_mm : float
        Half the distance between the two line points (e.g. half the sample
        side); a common scale, it cancels in the merge.

    Returns
    -------
    float, mm³
    """
    s = np.asarray(source_mm, dtype=np.float64)
    c = np.asarray(camera_center_mm, dtype=np.float64)
    u = np.zeros(3)
    u[:2] = np.asarray(strip_direction, dtype=np.float64).ravel()[:2]
    norm = np.linalg.norm(u)
    if s.shape != (3,) or c.shape != (3,) or norm == 0 or not np.isfinite(norm):
        raise MdfError(
            "tetrahedron_weight: source_mm and camera_center_mm must be 3-vectors and "
            f"strip_direction non-zero; got {source_mm}, {camera_center_mm}, {strip_direction}"
        )
    p1, p2 = -half_length_mm * u / norm, half_length_mm * u / norm
    return float(abs(np.linalg.det(np.stack([p1 - s, p2 - s, c - s]))) / 6.0)
