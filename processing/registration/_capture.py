"""Registering a frame as the archive holds it: frame + rig config + step record.

The offline ``btf`` stage (and the live worker) read a frame, the session's rig
config and the step that captured it; :func:`register_capture` picks the
camera's lens model and the view direction from them and registers the frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from processing.registration._errors import RegistrationError
from processing.registration._rectify import Region
from processing.registration._register import Registration, register_frame
from rig.archive import StepRecord
from rig.camera import PinholeCamera
from rig.config import RigConfig
from rig.errors import ConfigError, KinematicsError
from rig.kinds import rig_kind

__all__ = ["CaptureRegistration", "register_capture"]


@dataclass(frozen=True)
class CaptureRegistration:
    """One archived frame registered, with the directions its normtexture belongs to.

    Attributes
    ----------
    registration : Registration
        Normtexture, homography (reprojection error, reason) and markers.
    step : int
        The step index.
    camera : str
        The camera id.
    view_deg : (2,) float64
        (θ, φ) of this camera's view in the sample frame (the step's record).
    light_deg : (2,) float64 or None
        (θ, φ) of the light; None when no lamp was lit.
    """

    registration: Registration
    step: int
    camera: str
    view_deg: np.ndarray
    light_deg: np.ndarray | None


def register_capture(
    frame: np.ndarray,
    config: RigConfig,
    step: StepRecord,
    camera_id: str,
    *,
    size: int,
    camera: PinholeCamera | None = None,
    region: Region | None = None,
    extend_texels: int = 0,
    order: int = 1,
    filter: str = "box",
    from_pose: bool = False,
    min_markers: int = 3,
    max_reprojection_px: float = 1.0,
    max_noise_gain: float = 2.0,
) -> CaptureRegistration:
    """Register one archived frame onto the N×N texel grid of the sample.

    Parameters
    ----------
    frame : (H, W) or (H, W, C) array
        ``Archive.read_frame(step.index, camera_id, sub)``.
    config : RigConfig
        The session's rig config (``RigConfig.model_validate(archive.rig_config())``):
        the holder layout and, unless ``camera`` is given, the camera's nominal
        intrinsics and lens distortion.
    step : StepRecord
        The step that captured the frame (``archive.step_table()``).
    camera_id : str
        One of ``step.cameras``.
    size : int
        N, texels per side.
    camera : PinholeCamera, optional
        A calibrated model of the camera (only ``K`` and ``dist`` are used);
        default ``config.camera_model(camera_id)``.
    region, extend_texels, order, filter, min_markers, max_reprojection_px, max_noise_gain :
        As in :func:`register_frame`.
    from_pose : bool
        Register every frame from the camera model's pose (``camera``, or the rig
        config's nominal pose at the step's turntable angle), not from its markers.

    Returns
    -------
    CaptureRegistration
        Check ``registration.valid``; a flagged frame carries its reason. The
        markers are looked for where the camera posed by the step's recorded
        positions puts them, over the whole frame where that fails. On the
        Bonn lab a frame whose markers give no valid homography is registered from
        the camera the arm's and the rail's recorded state pose (reason
        ``FROM_RIG_POSE``).
    """
    if camera_id not in step.cameras:
        raise RegistrationError(
            f"camera_id = {camera_id!r} did not capture step {step.index}; "
            f"its cameras are {list(step.cameras)}"
        )
    given = camera is not None
    if camera is None:
        try:
            camera = config.camera_model(camera_id)
        except ConfigError as err:
            raise RegistrationError(
                f"camera {camera_id!r} of step {step.index} is not in the rig config: {err}"
            ) from err
    if camera_id not in step.views_deg:
        raise RegistrationError(
            f"step {step.index} records no view direction for camera {camera_id!r}; "
            f"it has {sorted(step.views_deg)}"
        )
    view = np.asarray(step.views_deg[camera_id], dtype=np.float64)
    light = None if step.light_deg is None else np.asarray(step.light_deg, dtype=np.float64)
    posed = _posed(config, step, camera_id, camera)
    expected = posed if posed is not None else _turned(config, step, camera_id, camera)
    if from_pose and posed is None:
        posed = camera if given else expected
    registration = register_frame(
        frame, config.holder, size=size, camera=camera, posed=posed, expected=expected,
        region=region, extend_texels=extend_texels, order=order, filter=filter,
        from_pose=from_pose, min_markers=min_markers,
        max_reprojection_px=max_reprojection_px, max_noise_gain=max_noise_gain,
    )  # fmt: skip
    return CaptureRegistration(registration, step.index, camera_id, view, light)


def _posed(
    config: RigConfig, step: StepRecord, camera_id: str, lens: PinholeCamera
) -> PinholeCamera | None:
    """Where the rig kind poses the camera from the step's recorded actuators (the Bonn lab:
    its arm and rail), with ``lens``'s intrinsics, scaled to the frames: frames whose
    markers fail register from it. None where the kind leaves it to the markers."""
    try:
        pose = rig_kind(config).posed_camera(config, camera_id, step.actuators)
    except KinematicsError as err:
        raise RegistrationError(f"step {step.index}: {err}") from err
    if pose is None:
        return None
    return PinholeCamera(lens.K, lens.dist, pose.R, pose.t, lens.width, lens.height)


def _turned(
    config: RigConfig, step: StepRecord, camera_id: str, lens: PinholeCamera
) -> PinholeCamera:
    """On a turntable rig, the nominal camera seen from the sample turned to the step's
    recorded ``turntable_deg``, with ``lens``'s intrinsics: where to look for the markers."""
    pose = config.camera_model(camera_id, turntable_deg=step.actuators.get("turntable_deg", 0.0))
    return PinholeCamera(lens.K, lens.dist, pose.R, pose.t, lens.width, lens.height)
