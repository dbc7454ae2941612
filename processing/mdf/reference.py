"""The reference region: image pixels that see the flat holder plate around the sample.

Seed ``001_…`` section 3.2 splits each laser scan image into a *reference
region* showing only the flat reference plane and the *sample region*; the laser
strip is a straight line in the reference region, which fixes the laser plane
of each frame. Here the split comes from geometry: a pixel belongs to the
reference region when its ray meets the reference plane z = 0 on the holder
plate, outside the sample square (plus a margin). Nothing lies above z = 0, so
such a pixel sees the plate itself.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from processing.mdf._errors import MdfError
from rig.camera import PinholeCamera

__all__ = ["ReferenceRegion", "plate_points", "profile_axis_for"]


def plate_points(camera: PinholeCamera, pixels) -> tuple[np.ndarray, np.ndarray]:
    """Where pixel rays meet the reference plane z = 0.

    Parameters
    ----------
    camera : PinholeCamera
        In the sample frame (mm).
    pixels : (n, 2) float
        Pixel coordinates (x = column, y = row), pixel centres at integers.

    Returns
    -------
    points : (n, 2) float64
        (x, y) on z = 0 in mm; 0 where the ray does not reach the plane.
    ok : (n,) bool
        True where the ray meets z = 0 in front of the camera.
    """
    origin, dirs = camera.rays(np.asarray(pixels, dtype=np.float64).reshape(-1, 2))
    dz = dirs[:, 2]
    ok = dz * -origin[2] > 1e-12  # the plane lies ahead along the ray
    t = np.where(ok, -origin[2] / np.where(ok, dz, 1.0), 0.0)
    points = origin[:2] + t[:, None] * dirs[:, :2]
    return np.where(ok[:, None], points, 0.0), ok


def profile_axis_for(camera: PinholeCamera, strip_direction) -> int:
    """The image axis along which to search for the laser strip.

    The strip is searched along the laser scan direction, i.e. across the
    strip: 0 (down the columns) when the strip runs closer to the image's
    horizontal, 1 (along the rows) otherwise.

    Parameters
    ----------
    strip_direction : (2,) or (3,) float
        Direction of the strip on the reference plane (sample frame).
    """
    u = np.asarray(strip_direction, dtype=np.float64).ravel()[:2]
    if not np.all(np.isfinite(u)) or np.linalg.norm(u) == 0:
        raise MdfError(f"strip_direction must be a finite non-zero vector, got {strip_direction}")
    u = u / np.linalg.norm(u)
    ends = np.array([[*(-10.0 * u), 0.0], [*(10.0 * u), 0.0]])
    pix, _ = camera.project(ends)
    dx, dy = np.abs(pix[1] - pix[0])
    return 0 if dx >= dy else 1


@dataclass(frozen=True)
class ReferenceRegion:
    """The reference region of one camera in the sample frame.

    Attributes
    ----------
    camera : PinholeCamera
        The camera, sample frame (mm).
    mask : (H, W) bool
        True for pixels that see the holder plate outside the sample square
        plus ``margin_mm``.
    footprint_mm : float
        Median side of a pixel's footprint on the reference plane inside the
        mask, mm per pixel: converts pixel tolerances to millimetres.
    """

    camera: PinholeCamera
    mask: np.ndarray
    footprint_mm: float

    @classmethod
    def from_holder(
        cls,
        camera: PinholeCamera,
        *,
        sample_mm: float,
        plate_mm: float,
        margin_mm: float = 2.0,
    ) -> ReferenceRegion:
        """Reference region of a camera looking at the holder plate.

        Parameters
        ----------
        sample_mm, plate_mm : float
            Sides of the sample square and the plate, centred on the origin
            (``RigConfig.holder``).
        margin_mm : float
            Kept clear of both the sample square and the plate edge, so the
            pre-filter never mixes in light from the recess or the floor.
        """
        if not 0 < sample_mm < plate_mm - 2 * margin_mm:
            raise MdfError(
                f"reference region: need 0 < sample_mm ({sample_mm}) < plate_mm ({plate_mm}) "
                f"- 2·margin_mm ({margin_mm}) so that some plate remains visible"
            )
        h, w = camera.height, camera.width
        rows, cols = np.mgrid[0:h, 0:w]
        pix = np.column_stack([cols.ravel(), rows.ravel()]).astype(np.float64)
        pts, ok = plate_points(camera, pix)
        pts = pts.reshape(h, w, 2)
        ok = ok.reshape(h, w)
        ax, ay = np.abs(pts[..., 0]), np.abs(pts[..., 1])
        on_plate = (ax <= plate_mm / 2 - margin_mm) & (ay <= plate_mm / 2 - margin_mm)
        off_sample = (ax >= sample_mm / 2 + margin_mm) | (ay >= sample_mm / 2 + margin_mm)
        mask = ok & on_plate & off_sample
        if not mask.any():
            raise MdfError(
                "reference region is empty: the camera does not see the holder plate around "
                f"the sample (sample {sample_mm} mm, plate {plate_mm} mm); check the camera pose"
            )
        # Footprint: sqrt of the area of the plate patch a pixel covers.
        du = np.diff(pts, axis=1)[:-1]
        dv = np.diff(pts, axis=0)[:, :-1]
        area = np.abs(du[..., 0] * dv[..., 1] - du[..., 1] * dv[..., 0])
        inner = mask[:-1, :-1] if mask[:-1, :-1].any() else np.ones_like(area, dtype=bool)
        footprint = float(np.median(np.sqrt(area[inner])))
        mask.setflags(write=False)
        return cls(camera=camera, mask=mask, footprint_mm=footprint)
