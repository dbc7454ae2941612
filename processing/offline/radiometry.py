"""Radiometric corrections of archived frames before the ``ps`` and ``btf`` stages.

When the archive's calibration has a response curve for a camera
(``rig calibrate response``), that camera's frames are linearised before they
are registered: a value v becomes ``curve[v]``, the relative exposure that
gives v (1 at v = 128), so registration averages light, not camera values.
When it names lamp flat fields (``rig calibrate lamps``: each lamp's image of
the white target over its value at the centre), a lamp's frames are divided by
its map *on the texel grid*, after registration: the map is carried from the
white session's camera onto the sample frame once, so one map serves every
view. The map was measured with arc and turntable at 0°; a texel of a step at
arc a and turntable t sees the lamp as the point turned by t − a about the
axis saw it then.

The archive keeps a copy of the flat-field store (``calibration/<name>``,
:func:`rig.material.archive_flat_field_path`), written when its calibration is
set. ``rig process --raw`` switches every correction off. What was applied and
from which calibration goes into the material (``rig.material.Radiometry``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import ndimage

from processing.offline.runner import calibrated_camera, calibration_fit
from processing.offline.texel_light import plane_irradiance
from processing.registration import Registration, rectify
from rig.archive import Archive, StepRecord
from rig.calfile import CalibrationFile
from rig.camera import PinholeCamera
from rig.config import RigConfig
from rig.errors import ConfigError
from rig.geometry import texel_centers_mm
from rig.kinematics import lamp_position_mm, rotate_z
from rig.material import (
    FlatFieldMaps,
    MaterialError,
    Radiometry,
    archive_flat_field_path,
    read_flat_field,
)

__all__ = [
    "FLAT_FLOOR",
    "FLAT_MARGIN",
    "FLAT_SMOOTHING",
    "FrameCorrections",
    "calibration_source",
    "frame_corrections",
    "point_falloff",
]

#: A flat-field value below this (of the centre's) is a texel the lamp barely
#: lights: it is divided by this floor, not by a value dominated by noise.
FLAT_FLOOR = 0.05
#: σ of the Gaussian that averages a flat-field map's pixel noise out, as a
#: fraction of the map's width (fall-off changes over tens of percent of it).
FLAT_SMOOTHING = 0.01
#: The flat field is read this fraction of the sample's side inside its edges.
FLAT_MARGIN = 0.05


@dataclass(frozen=True)
class FrameCorrections:
    """The corrections an archive's calibration offers, ready to apply.

    curves : camera id → (256, C) float32 inverse response, 1 at value 128
    flat_field : each lamp's map as the white session's camera saw it, or None
    flat_camera : that camera's model at the maps' size, turntable 0°
    target_z_mm : the white target's height (where the maps were measured)
    calibration_version : the archive's calibration version (0: none)
    sources : correction → its calibration session and time
    skipped : what is not corrected → why
    """

    curves: dict[str, np.ndarray] = field(default_factory=dict)
    flat_field: FlatFieldMaps | None = None
    flat_camera: PinholeCamera | None = None
    target_z_mm: float = 0.0
    calibration_version: int = 0
    sources: dict[str, str] = field(default_factory=dict)
    skipped: dict[str, str] = field(default_factory=dict)

    def linear(self, frame: np.ndarray, camera_id: str) -> np.ndarray | None:
        """(H, W, C) float32 relative exposure of an 8-bit frame of ``camera_id``
        (1 at value 128); None when that camera's frames stay as recorded."""
        curve = self.curves.get(camera_id)
        if curve is None or frame.dtype != np.uint8:
            return None
        image = frame if frame.ndim == 3 else frame[:, :, None]
        channels = np.arange(image.shape[2]) % curve.shape[1]
        return curve[image, channels]

    def normtexture(
        self,
        frame: np.ndarray,
        registration: Registration,
        step: StepRecord,
        camera_id: str,
        config: RigConfig,
        *,
        lens: PinholeCamera,
        size: int,
        lamp_model: bool,
        filter: str = "box",
    ) -> tuple[np.ndarray, np.ndarray]:
        """(size, size, C) float64 corrected normtexture of a registered frame, and the
        (size, size) bool texels the lamp's flat field barely lights (divided by
        ``FLAT_FLOOR``; none without a flat field).

        Linear (relative exposure, 1 at value 128) when the camera has a curve,
        else the registered values over full scale; divided by the lamp's flat
        field on the texel grid when there is one — with ``lamp_model`` by the
        part the near-lamp model (cos θ / r², :func:`point_falloff`) does not
        explain, for solvers that model it themselves. ``filter``: the resampling
        filter of the linearised frame (``processing.registration.rectify``).
        """
        sample_mm = config.holder.sample_mm
        linear = self.linear(frame, camera_id)
        if linear is None:
            full_scale = float(2 ** config.camera(camera_id).bit_depth - 1)
            texture = registration.normtexture.texture.astype(np.float64) / full_scale
        else:
            texture = rectify(
                linear,
                registration.homography,
                sample_mm=sample_mm,
                size=size,
                camera=lens,
                filter=filter,
            ).texture.astype(np.float64)
        if self.flat_field is None or step.lamp not in self.flat_field.lamps:
            return texture, np.zeros((size, size), bool)
        points = _texel_points(
            sample_mm, size, self.target_z_mm,
            arc_deg=step.actuators.get("arc_deg", 0.0),
            turntable_deg=step.actuators.get("turntable_deg", 0.0),
        )  # fmt: skip
        # Turned texels leave the white square at its corners, and its rim blurs
        # with the holder: the map is read inside, as its part the lamp model does
        # not explain (smooth), and carried out with the model.
        limit = sample_mm / 2 * (1.0 - 2 * FLAT_MARGIN)
        inside = points.copy()
        inside[..., :2] = np.clip(points[..., :2], -limit, limit)
        pixels, _ = self.flat_camera.project(inside.reshape(-1, 3))
        falloff = self.flat_field.falloff[self.flat_field.lamps.index(step.lamp)]
        # The fall-off is smooth and the white frame noisy: average the noise out
        # before sampling, or each texel inherits one pixel's shot noise.
        sigma = FLAT_SMOOTHING * falloff.shape[1]
        smooth = ndimage.gaussian_filter(falloff.astype(np.float64), sigma, mode="nearest")
        measured = ndimage.map_coordinates(
            smooth, [pixels[:, 1], pixels[:, 0]], order=1, mode="nearest"
        ).reshape(size, size)
        flat = measured / point_falloff(config, step.lamp, inside, self.target_z_mm)
        if not lamp_model:
            flat = flat * point_falloff(config, step.lamp, points, self.target_z_mm)
        # not-a-number too (a lamp in the target's plane: the model's fall-off is 0 / 0)
        floored = ~(flat >= FLAT_FLOOR)
        return texture / np.where(floored, FLAT_FLOOR, flat)[..., None], floored

    def record(self, *, cameras, lamps) -> Radiometry:
        """What was applied to frames of ``cameras`` under ``lamps``, for the material."""
        linearised = tuple(sorted(c for c in set(cameras) if c in self.curves))
        flat = self.flat_field
        flat_fielded = tuple(sorted(x for x in set(lamps) if flat is not None and x in flat.lamps))
        skipped = dict(self.skipped)
        for camera in sorted(set(cameras) - set(linearised)):
            if "response" not in skipped:
                skipped.setdefault(camera, "no response curve for this camera: frames as recorded")
        for lamp in sorted(set(lamps) - set(flat_fielded)):
            if flat is not None:
                skipped[lamp] = "the flat fields have no map of this lamp"
        return Radiometry(
            linearised, flat_fielded, self.calibration_version, dict(self.sources), skipped
        )


def frame_corrections(archive: Archive, config: RigConfig, *, raw: bool = False):
    """The corrections of ``archive``'s calibration (none with ``raw``)."""
    if raw:
        return FrameCorrections(skipped={"all": "rig process --raw: frames as recorded"})
    calibration, skipped = calibration_fit(archive)
    if calibration is None:
        return FrameCorrections(skipped=skipped)
    sources = {}
    curves = {cam: np.asarray(r.curve, np.float32) for cam, r in calibration.response.items()}
    for camera in sorted(curves):
        bits = _bit_depth(config, camera)
        if bits != 8:
            del curves[camera]
            skipped[camera] = (
                f"{bits}-bit frames, an 8-bit response curve: frames as recorded"
                if bits
                else "a response curve for a camera this rig does not have"
            )
    if curves:
        sources["response"] = calibration_source(calibration, "response")
    else:
        skipped["response"] = "the calibration has no response curve: frames as recorded"
    maps, camera = _flat_field(archive, config, calibration, skipped)
    if maps is not None:
        sources["flat_field"] = calibration_source(calibration, "lamps")
    return FrameCorrections(
        curves, maps, camera, config.targets.white.height_mm, archive.calibration_version,
        sources, skipped,
    )  # fmt: skip


def _texel_points(
    sample_mm: float, size: int, z_mm: float, *, arc_deg: float, turntable_deg: float
) -> np.ndarray:
    """(size, size, 3) where the texels of a step at ``arc_deg``/``turntable_deg`` lie
    relative to the lamps as they stood when the flat fields were measured (0°, 0°),
    on the plane z = ``z_mm``."""
    xy = texel_centers_mm(sample_mm, size)
    points = np.concatenate([xy, np.full((size, size, 1), z_mm)], axis=-1)
    return rotate_z(points, turntable_deg - arc_deg)


def point_falloff(config: RigConfig, lamp: str, points: np.ndarray, z_mm: float) -> np.ndarray:
    """What the lamp model alone predicts of the flat field at ``points`` (…, 3):
    cos θ / r² on the plane z = ``z_mm`` over its value at (0, 0, z_mm) for a
    near lamp at its arc-0° position, 1 for a directional one."""
    if config.lamp(lamp).kind == "directional":
        return np.ones(points.shape[:-1])
    source = lamp_position_mm(config, lamp, arc_deg=0.0, turntable_deg=0.0)
    return plane_irradiance(source, points) / plane_irradiance(source, np.array([0.0, 0.0, z_mm]))


def _bit_depth(config: RigConfig, camera: str) -> int | None:
    try:
        return config.camera(camera).bit_depth
    except ConfigError:
        return None


def calibration_source(calibration: CalibrationFile, section: str) -> str:
    """The session and time a calibration section was measured, for the material."""
    provenance = getattr(calibration, f"{section}_provenance")
    if provenance is None:
        return "calibration file (no provenance recorded)"
    return f"{provenance.archive or 'unknown session'} ({provenance.created})"


def _flat_field(archive: Archive, config: RigConfig, calibration: CalibrationFile, skipped):
    name = calibration.lamps_flat_field
    if name is None:
        skipped["flat_field"] = "the calibration names no flat fields: frames as recorded"
        return None, None
    path = archive_flat_field_path(archive.path, name)
    try:
        maps = read_flat_field(path)
    except MaterialError as err:
        skipped["flat_field"] = (
            f"the calibration names {name} but the archive has no readable copy ({err}); "
            "store it with rig calibrate lamps --apply ARCHIVE"
        )
        return None, None
    try:
        width = config.camera(maps.camera).width
    except ConfigError:
        skipped["flat_field"] = (
            f"the flat fields were seen by camera {maps.camera!r}, which this rig does not have"
        )
        return None, None
    camera = calibrated_camera(
        config, calibration, maps.camera, 0.0, scale=maps.falloff.shape[2] / width
    )
    return maps, camera
