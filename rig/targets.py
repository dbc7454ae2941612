"""The calibration targets of a rig: what is placed on the turntable to calibrate.

Each target is a physical part whose geometry calibration relies on and the
simulator renders, so both read it from here (``RigConfig.targets``):

- ``charuco``: a ChArUco board printed on a wedge, tilted by ``tilt_deg`` about
  the sample's y axis, its low edge on the reference plane. The tilt makes the
  board's plane differ between turntable angles, which a planar board lying
  flat cannot (its images all share one plane up to a rotation about its
  normal, which leaves the intrinsics undetermined).
- ``sphere``: a mirror (chrome) ball resting on the reference plane, its centre
  ``offset_mm`` from the turntable axis along the sample's +x.
- ``white``: a flat diffuse target of known reflectance on the reference plane.
- ``laser``: a stepped block: bands along the sample's y axis at the listed
  heights above the reference plane, so a laser strip across them breaks into
  one segment per height (seed 001 §3.2).

Frames (all in mm): the *sample* frame turns with the turntable; at turntable
0° it is the world frame of ``rig.config``.
"""

from __future__ import annotations

import cv2
import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

__all__ = ["CharucoTarget", "LaserStepTarget", "MirrorSphere", "Targets", "WhiteTarget"]


class _Closed(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class CharucoTarget(_Closed):
    """A ChArUco board on a wedge (OpenCV's board layout: corner 0 at the
    board's top-left, x along the squares_x side, y down the board)."""

    squares_x: int = Field(10, ge=3, le=40)
    squares_y: int = Field(7, ge=3, le=40)
    square_mm: float = Field(13.0, gt=0)
    marker_mm: float = Field(8.0, gt=0)
    dictionary: str = "DICT_5X5_100"
    tilt_deg: float = Field(40.0, ge=0, le=60, description="wedge angle about the sample y axis")

    @model_validator(mode="after")
    def _marker_in_square(self) -> CharucoTarget:
        if self.marker_mm >= self.square_mm:
            raise ValueError(
                f"marker_mm ({self.marker_mm}) must be smaller than square_mm ({self.square_mm})"
            )
        if not self.dictionary.startswith("DICT_") or not hasattr(cv2.aruco, self.dictionary):
            raise ValueError(f"unknown ArUco dictionary {self.dictionary!r}; use a DICT_* name")
        return self

    @property
    def size_mm(self) -> tuple[float, float]:
        """(width along the slope, height) of the board."""
        return self.squares_x * self.square_mm, self.squares_y * self.square_mm

    def board(self) -> cv2.aruco.CharucoBoard:
        dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, self.dictionary))
        return cv2.aruco.CharucoBoard(
            (self.squares_x, self.squares_y), self.square_mm, self.marker_mm, dictionary
        )

    def board_pose(self) -> tuple[np.ndarray, np.ndarray]:
        """(R, t): a board point b maps to the sample frame as ``R @ b + t``.

        The board is centred on the wedge, which rises from z = 0 at its
        low edge (x = −w/2 cos t) to its high edge; board x runs up the slope,
        board y along the sample's −y.
        """
        t = np.deg2rad(self.tilt_deg)
        w, h = self.size_mm
        ex = np.array([np.cos(t), 0.0, np.sin(t)])
        ey = np.array([0.0, -1.0, 0.0])
        R = np.column_stack([ex, ey, np.cross(ex, ey)])
        centre = np.array([0.0, 0.0, w / 2 * np.sin(t)])
        return R, centre - R @ np.array([w / 2, h / 2, 0.0])


class MirrorSphere(_Closed):
    """A chrome ball resting on the reference plane."""

    radius_mm: float = Field(25.0, gt=0)
    offset_mm: float = Field(
        40.0, ge=0, description="centre's distance from the turntable axis: the baseline of a "
        "near lamp's triangulation (25 mm gives ~1 % of its distance, 40 mm better)"
    )

    def centre_mm(self, turntable_deg: float = 0.0) -> np.ndarray:
        """The ball's centre in the world frame with the turntable at an angle."""
        a = np.deg2rad(turntable_deg)
        return np.array([self.offset_mm * np.cos(a), self.offset_mm * np.sin(a), self.radius_mm])


class WhiteTarget(_Closed):
    """A flat diffuse (Lambertian) target on the reference plane."""

    reflectance: float = Field(0.8, gt=0, le=1)
    height_mm: float = Field(-0.5, ge=-100, lt=0, description="its surface's z: in the recess")


class LaserStepTarget(_Closed):
    """Bands of equal width along y, band i at ``heights_mm[i]`` above z = 0."""

    heights_mm: tuple[float, ...] = Field((0.0, 10.0), min_length=2, max_length=16)

    @model_validator(mode="after")
    def _heights(self) -> LaserStepTarget:
        if any(h < 0 for h in self.heights_mm):
            raise ValueError(f"heights_mm must be ≥ 0, got {list(self.heights_mm)}")
        return self

    def band_edges_mm(self, sample_mm: float) -> np.ndarray:
        """(k + 1,) y coordinates of the band edges across the sample area."""
        return np.linspace(-sample_mm / 2, sample_mm / 2, len(self.heights_mm) + 1)


class Targets(_Closed):
    charuco: CharucoTarget = CharucoTarget()
    sphere: MirrorSphere = MirrorSphere()
    white: WhiteTarget = WhiteTarget()
    laser: LaserStepTarget = LaserStepTarget()
