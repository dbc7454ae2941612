"""One frame in, one normtexture (or a flag) out: detect → fit → rectify."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from processing.registration._errors import Reason, RegistrationError
from processing.registration._homography import (
    PlaneHomography,
    fit_plane_homography,
    pose_plane_homography,
)
from processing.registration._markers import MarkerDetection, detect_markers
from processing.registration._predicted import expected_corners_px, track_markers
from processing.registration._rectify import Normtexture, Region, rectify
from rig.camera import PinholeCamera
from rig.config import Holder

__all__ = ["Registration", "register_frame"]


@dataclass(frozen=True)
class Registration:
    """The result of registering one frame.

    Attributes
    ----------
    normtexture : Normtexture
        The rectified texture; all zeros and all invalid when the frame is
        flagged (it is never warped with a bad homography).
    homography : PlaneHomography
        The fit, its reprojection errors and the reason (``FROM_RIG_POSE``
        when the posed camera model stood in for the markers).
    detection : MarkerDetection
        The markers found.
    """

    normtexture: Normtexture
    homography: PlaneHomography
    detection: MarkerDetection

    @property
    def valid(self) -> bool:
        return self.homography.valid

    @property
    def reason(self) -> Reason:
        return self.homography.reason


def register_frame(
    frame: np.ndarray,
    holder: Holder,
    *,
    size: int,
    camera: PinholeCamera | None = None,
    posed: PinholeCamera | None = None,
    expected: PinholeCamera | None = None,
    region: Region | None = None,
    extend_texels: int = 0,
    order: int = 1,
    filter: str = "box",
    from_pose: bool = False,
    min_markers: int = 3,
    max_reprojection_px: float = 1.0,
    max_noise_gain: float = 2.0,
) -> Registration:
    """Register a raw BTF frame onto the N×N texel grid of the holder's sample square.

    Parameters
    ----------
    frame : (H, W) or (H, W, C) array
        Raw camera frame, C ∈ {1, 3}, integer or float.
    holder : rig.config.Holder
        The plate: marker dictionary, layout and sample square.
    size : int
        N, texels per side of the normtexture.
    camera : PinholeCamera, optional
        Its ``K`` and ``dist`` undistort the marker corners and the sampling
        (the pose is not used: the markers give it).
    posed : PinholeCamera, optional
        The camera model posed in the sample frame from the rig's reported
        positions (``rig.bonn.camera_model``). Where the markers give no valid
        homography, the frame is rectified through this model's plate-plane
        homography (:func:`pose_plane_homography`, its lens for the sampling)
        and flagged ``Reason.FROM_RIG_POSE``: valid, but distinguishable.
        Without it such a frame keeps the markers' reason.
    expected : PinholeCamera, optional
        The camera model (lens included) posed in the sample frame from the
        rig's recorded positions, good to about a third of a marker module.
        The markers are then refined where it puts them and checked by their
        bits (:func:`track_markers`, without OpenCV's detector); where
        they give no valid homography, the detector searches the whole frame.
    region, extend_texels, order, filter :
        Passed to :func:`rectify`.
    from_pose : bool
        Rectify through ``posed``'s homography even where the markers give one
        (reason ``FROM_RIG_POSE``): where the pose is known exactly, as in the
        simulator, registration without the markers' error.
    min_markers, max_reprojection_px, max_noise_gain :
        Passed to :func:`fit_plane_homography`.

    Returns
    -------
    Registration
        Check ``valid``; ``homography.mean_reprojection_px`` is the per-frame
        marker reprojection error in pixels (0 for ``Reason.FROM_RIG_POSE``).

    Examples
    --------
    >>> from rig.config import default_rig_config
    >>> import numpy as np
    >>> blank = np.zeros((64, 64), np.uint8)
    >>> register_frame(blank, default_rig_config().holder, size=16).reason.name
    'TOO_FEW_MARKERS'
    """

    def fit(detection: MarkerDetection) -> PlaneHomography:
        return fit_plane_homography(
            detection,
            holder,
            camera=camera,
            min_markers=min_markers,
            max_reprojection_px=max_reprojection_px,
            max_noise_gain=max_noise_gain,
        )

    homography = None
    if expected is not None:
        detection = track_markers(frame, holder, expected_corners_px(expected, holder))
        homography = fit(detection)
    if homography is None or not homography.valid:
        detection = detect_markers(frame, holder)
        homography = fit(detection)
    n = size + extend_texels
    if from_pose and posed is None:
        raise RegistrationError("from_pose: no posed camera model to register from")
    if (from_pose or not homography.valid) and posed is not None:
        by_pose = pose_plane_homography(posed, holder)
        if by_pose.valid:
            homography, camera = by_pose, posed
    if not homography.valid:
        channels = 1 if np.ndim(frame) == 2 else np.shape(frame)[2]
        blank = Normtexture(np.zeros((n, n, channels), np.float32), np.zeros((n, n), bool), (0, 0))
        return Registration(blank, homography, detection)
    texture = rectify(
        frame,
        homography,
        sample_mm=holder.sample_mm,
        size=size,
        camera=camera,
        region=region,
        extend_texels=extend_texels,
        order=order,
        filter=filter,
    )
    return Registration(texture, homography, detection)
