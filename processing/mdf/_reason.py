"""Per-pixel and per-texel reason codes of the MDF reconstruction."""

from __future__ import annotations

from enum import IntEnum

import numpy as np

__all__ = ["Reason", "reason_counts"]


class Reason(IntEnum):
    """Why a pixel's peak or a texel's distance is (or is not) valid.

    Stored as ``uint8``. OK and EDGE carry a value; every other code means the
    value is -1. Codes are ordered by how much they tell: when no laser
    location gave a texel a value, the merged reason is the largest code any
    location reported (e.g. GRAZING beats UNLIT).
    """

    OK = 0
    #: Valid, but the neighbouring pixels disagree by more than ``edge_tol_px``
    #: (a depth or shadow edge): the value comes from the nearest pixel alone.
    EDGE = 1
    #: The texel's reference point does not project into the image.
    OUTSIDE_IMAGE = 2
    #: The pixel never rose ``min_contrast`` above its darkest frame: the laser
    #: never lit what it sees (occluded or shadowed).
    UNLIT = 3
    #: The peak lies too close to the first or last frame for the detector's
    #: window: the sheet may have peaked outside the sweep.
    AT_SEQUENCE_EDGE = 4
    #: The peak detector found no concave peak in the window.
    FIT_FAILED = 5
    #: A frame around the peak time has no laser plane (no line in the
    #: reference region).
    NO_PLANE = 6
    #: The triangulated point lies above the reference plane by more than
    #: ``above_tol_px``: an inconsistent plane or a spurious peak.
    ABOVE_REFERENCE = 7
    #: The laser plane is nearly parallel to the view ray: a small plane error
    #: would move the point by more than ``max_error_gain`` times as much.
    GRAZING = 8


def reason_counts(reason) -> dict[str, int]:
    """Number of entries per :class:`Reason` name (only the reasons present)."""
    counts = np.bincount(np.asarray(reason, dtype=np.uint8).ravel(), minlength=len(Reason))
    return {Reason(code).name: int(n) for code, n in enumerate(counts[: len(Reason)]) if n}
