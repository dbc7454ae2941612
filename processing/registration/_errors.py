"""The registration domain error and the reasons a frame is flagged."""

from enum import IntEnum

from rig.errors import RigError


class RegistrationError(RigError, ValueError):
    """Malformed input to a registration function.

    The message names the argument, the value that was wrong and what would be
    valid. A frame that is well formed but cannot be registered (too few
    markers, say) is not an error: it comes back flagged with a :class:`Reason`.
    """


class Reason(IntEnum):
    """Why a frame's homography is usable or not; the first failing check wins.

    ``OK`` and ``FROM_RIG_POSE`` are usable; the others flag the frame.
    """

    OK = 0
    #: Fewer markers found than ``min_markers``.
    TOO_FEW_MARKERS = 1
    #: The marker corners found lie (nearly) on one line on the plate.
    COLLINEAR_MARKERS = 2
    #: The fit would amplify corner noise too much at the sample square
    #: (markers bunched far from the sample, or a degenerate view).
    ILL_CONDITIONED = 3
    #: The mean marker reprojection error exceeds ``max_reprojection_px``.
    HIGH_REPROJECTION = 4
    #: The sample square does not project in front of the camera.
    SAMPLE_NOT_VISIBLE = 5
    #: Usable, but from the rig's reported pose, not the markers: the markers
    #: gave no valid homography and the posed camera model's plane homography
    #: was used instead (a grazing view where no marker is found, say).
    FROM_RIG_POSE = 6
