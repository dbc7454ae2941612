"""What a photometric-stereo solve returns: maps, a validity mask and reasons."""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum

import numpy as np

#: Condition number stored for a pixel whose light system is singular.
CONDITION_CAP = 1.0e12


class Reason(IntEnum):
    """Why a pixel is valid or not (stored as ``uint8`` in ``PhotometricResult.reason``).

    When several apply, the first in this order wins: MASKED, COPLANAR_LIGHTS,
    DARK, SATURATED, TOO_FEW_LIGHTS, ILL_CONDITIONED, BELOW_HORIZON.
    """

    OK = 0
    #: Outside the caller's mask; not solved.
    MASKED = 1
    #: The pixel's full light set is (nearly) coplanar: its condition number
    #: exceeds ``max_condition`` before any observation was rejected.
    COPLANAR_LIGHTS = 2
    #: No observation above ``dark_level`` (or the fitted albedo is not positive).
    DARK = 3
    #: Fewer than 3 observations below ``saturation_level``.
    SATURATED = 4
    #: Fewer than 3 observations left after shadow/highlight rejection.
    TOO_FEW_LIGHTS = 5
    #: The lights left after rejection form a system above ``max_condition``.
    ILL_CONDITIONED = 6
    #: The fitted normal points below the sample plane (n_z < 0).
    BELOW_HORIZON = 7


@dataclass(frozen=True)
class PhotometricResult:
    """Per-pixel photometric-stereo solution of one view.

    Attributes
    ----------
    normals : (H, W, 3) float32
        Unit normals in the sample frame (z up). Invalid pixels hold (0, 0, 1).
    albedo : (H, W) or (H, W, 3) float32
        Lambertian albedo in normalised intensity units (integer images are
        divided by their dtype's maximum; floats are taken as they are) per
        unit lamp intensity. Invalid pixels hold 0.
    valid : (H, W) bool
        True where ``reason == Reason.OK``.
    reason : (H, W) uint8
        A :class:`Reason` code per pixel.
    condition : (H, W) float32
        Condition number (ratio of the extreme singular values) of the
        weighted light matrix that was solved; ``CONDITION_CAP`` where it is
        singular, 0 where no system was formed (masked, dark, too few lights).
    residual : (H, W) float32
        Root-mean-square residual of the fit over the observations used, in
        the same units as ``albedo`` (weighted RMS for robust weights); 0 for
        invalid pixels.
    lights_used : (H, W) uint16
        Number of observations with a non-zero weight.
    """

    normals: np.ndarray
    albedo: np.ndarray
    valid: np.ndarray
    reason: np.ndarray
    condition: np.ndarray
    residual: np.ndarray
    lights_used: np.ndarray

    def reason_counts(self) -> dict[str, int]:
        """Number of pixels per :class:`Reason` name (only the reasons that occur)."""
        counts = np.bincount(self.reason.ravel(), minlength=len(Reason))
        return {Reason(code).name: int(n) for code, n in enumerate(counts) if n}
