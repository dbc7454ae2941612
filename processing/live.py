"""Live stages: what the daemon's workers compute while a session runs.

Each stage is a function ``(image, header) → dict[name, ndarray]`` of one
streamed frame and its header (``orchestrator.daemon.protocol.FrameHeader`` as a dict);
it returns ``{}`` for frames that are not its kind. The session's archive (its
path travels in the header; a worker on another machine needs it on a shared
file system) supplies the rig config, the plan and the committed steps: the
daemon commits a step before it streams its frames.

- ``register`` (btf and ps frames): the frame rectified onto the texel grid,
  with its validity and the marker reprojection error (issue: registration).
- ``laser`` (mdf frames): the laser line on the reference plane and its fit
  (the per-frame half of the MDF; merging runs in ``rig process``).
- ``ps`` (ps frames): when a frame completes its view (the last lamp of that
  camera and turntable angle in the plan), the view's photometric stereo from
  the archive — normals, albedo, validity, height.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from functools import lru_cache
from pathlib import Path

import numpy as np

from processing.mdf import ReferenceRegion, frame_laser_line
from processing.offline.ps import PsStage
from processing.offline.runner import View, archive_calibration, calibrated_camera
from processing.registration import register_frame
from rig.archive import Archive, StepRecord
from rig.config import RigConfig
from rig.kinematics import laser_source_mm
from rig.plan import parse_plan
from rig.schedule import compile_plan

__all__ = ["LIVE_STAGES", "LiveSession", "live_laser_line", "live_ps", "live_register"]

#: texels per side of the live maps
LIVE_SIZE = 128


class LiveSession:
    """A session's archive as the live stages read it (cached; re-read for new steps)."""

    def __init__(self, path: str | Path):
        self.path = str(path)
        self._lock = threading.Lock()
        with Archive.open(self.path, mode="r") as archive:
            self.config = RigConfig.model_validate(archive.rig_config)
            self.plan_toml = archive.plan_toml
            self._scale = float(archive.plan.get("resolution", {}).get("scale", 1.0))
            self._steps = {s.index: s for s in archive.step_table()}
            self._calibration = archive_calibration(archive)
        self._views: dict[int, View] | None = None

    def step(self, index: int) -> StepRecord:
        """The committed step ``index`` (the archive is re-read once if it is new)."""
        with self._lock:
            if index not in self._steps:
                with Archive.open(self.path, mode="r") as archive:
                    self._steps = {s.index: s for s in archive.step_table()}
            return self._steps[index]

    def lens(self, camera_id: str, turntable_deg: float = 0.0):
        """The camera of the archived frames: sample frame at ``turntable_deg``, intrinsics
        at the plan's resolution, calibrated where the archive's calibration has it
        (as ``processing.offline.frame_camera``)."""
        return calibrated_camera(
            self.config, self._calibration, camera_id, turntable_deg, scale=self._scale
        )

    def ps_view_completed_by(self, step: int, camera: str) -> View | None:
        """The ps view whose last planned step is ``step`` (seen by ``camera``), if any."""
        with self._lock:
            if self._views is None:
                schedule = compile_plan(parse_plan(self.plan_toml or ""), self.config)
                views: dict[tuple[str, float], list[int]] = {}
                for s in schedule.steps:
                    if s.kind == "ps":
                        for cam in s.cameras:
                            key = (cam, round(float(s.turntable_deg), 1) % 360.0)
                            views.setdefault(key, []).append(s.index)
                self._views = {}
                for (cam, turntable), steps in views.items():
                    name = f"{cam}_tt{turntable:05.1f}"
                    self._views[(max(steps), cam)] = View(name, cam, turntable, tuple(steps))
            return self._views.get((step, camera))


@lru_cache(maxsize=4)
def _session(path: str) -> LiveSession:
    return LiveSession(path)


def _session_of(header: dict) -> LiveSession:
    if not header.get("archive"):
        raise ValueError("this live stage needs the session's archive path in the frame header")
    return _session(header["archive"])


def live_register(image: np.ndarray, header: dict, *, size: int = LIVE_SIZE) -> dict:
    """btf/ps frames → ``texture`` (N, N, C) float32, ``valid`` (N, N), ``reason``
    (``processing.registration.Reason``; a flagged frame's texture is all zero) and
    ``reprojection_px`` (the fit's mean marker error, 0 when too few markers to fit)."""
    if header["kind"] not in ("btf", "ps"):
        return {}
    session = _session_of(header)
    holder = session.config.holder
    reg = register_frame(image, holder, size=size, camera=session.lens(header["camera"]))
    return {
        "texture": reg.normtexture.texture.astype(np.float32),
        "valid": reg.normtexture.valid & reg.valid,
        "reason": np.uint8(reg.reason),
        "reprojection_px": np.float32(reg.homography.mean_reprojection_px),
    }


@lru_cache(maxsize=32)
def _region(path: str, camera_id: str, turntable_deg: float) -> ReferenceRegion:
    session = _session(path)
    holder = session.config.holder
    return ReferenceRegion.from_holder(
        session.lens(camera_id, turntable_deg), sample_mm=holder.sample_mm, plate_mm=holder.plate_mm
    )


def live_laser_line(image: np.ndarray, header: dict) -> dict:
    """mdf frames → the laser line ``normal`` (2,), ``rho_mm``, ``reason``, ``inliers``."""
    if header["kind"] != "mdf":
        return {}
    session = _session_of(header)
    step = session.step(header["step"])
    turntable, arc = step.actuators["turntable_deg"], step.actuators["arc_deg"]
    region = _region(session.path, header["camera"], round(float(turntable), 6))
    source = laser_source_mm(session.config, step.laser, arc_deg=arc, turntable_deg=turntable)
    line = frame_laser_line(image, region, source_mm=source)
    return {
        "normal": np.asarray(line.normal, np.float32),
        "rho_mm": np.float32(line.rho_mm),
        "reason": np.uint8(line.reason),
        "inliers": np.int32(line.inliers),
    }


def live_ps(image: np.ndarray, header: dict, *, size: int = LIVE_SIZE) -> dict:
    """The frame completing a ps view → that view's normals, albedo, valid, height."""
    if header["kind"] != "ps":
        return {}
    session = _session_of(header)
    view = session.ps_view_completed_by(header["step"], header["camera"])
    if view is None:
        return {}
    result = PsStage(size=size).compute(session.path, view)
    return {
        "normals": result["normals"],
        "albedo": result["albedo"],
        "valid": result["valid"],
        "height_mm": result["height_mm"],
    }


#: stage name → function of one frame and its header
LIVE_STAGES: dict[str, Callable[[np.ndarray, dict], dict]] = {
    "register": live_register,
    "laser": live_laser_line,
    "ps": live_ps,
}
