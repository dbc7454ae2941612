"""Live stages: what the daemon's workers compute while a session runs.

Each stage is a function ``(image, header) → dict[name, ndarray]`` of one
streamed frame and its header (``orchestrator.wire.protocol.FrameHeader`` as a dict);
it returns ``{}`` for frames that are not its kind. The session's archive (its
path travels in the header; a worker on another machine needs it on a shared
file system) supplies the rig config, the plan and the committed steps: the
daemon commits a step before it streams its frames. What a worker knows of a
session is kept by the session's id (a new session in the same archive path
starts afresh), for the last few sessions.

- ``register`` (btf and ps frames): the frame rectified onto the texel grid,
  with its validity and the marker reprojection error.
- ``laser`` (mdf frames): the laser line on the reference plane and its fit
  (the per-frame half of the MDF; merging runs in ``rig process``).
- ``ps`` (ps frames): when a frame completes its view (the last lamp of that
  camera and turntable angle in the plan), the view's photometric stereo —
  normals, albedo, validity, height. The worker keeps the view's frames as they
  stream past and reads from the archive only those another worker was sent.
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from collections.abc import Callable
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
        self._regions: dict[tuple[str, float], ReferenceRegion] = {}
        # (camera, step) → (the view's last step, the frame's sub 0)
        self._ps_frames: dict[tuple[str, int], tuple[int, np.ndarray]] = {}
        with Archive.open(self.path, mode="r") as archive:
            self.config = RigConfig.model_validate(archive.rig_config)
            self.plan_toml = archive.plan_toml
            self._scale = float(archive.plan.get("resolution", {}).get("scale", 1.0))
            self._steps = {s.index: s for s in archive.step_table()}
            self._calibration = archive_calibration(archive)
        self._views: dict[tuple[int, str], View] | None = None

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

    def ps_view_of(self, step: int, camera: str) -> View | None:
        """The ps view that ``camera``'s frame of ``step`` belongs to, if any."""
        with self._lock:
            if self._views is None:
                schedule = compile_plan(parse_plan(self.plan_toml or ""), self.config)
                views: dict[tuple[str, float], list[int]] = {}
                for s in schedule.steps:
                    if s.kind == "ps":
                        for cam in s.cameras:
                            key = (cam, round(float(s.pose.turntable_deg), 1) % 360.0)
                            views.setdefault(key, []).append(s.index)
                self._views = {}
                for (cam, turntable), steps in views.items():
                    view = View(f"{cam}_tt{turntable:05.1f}", cam, turntable, tuple(steps))
                    self._views.update({(index, cam): view for index in steps})
            return self._views.get((step, camera))

    def region(self, camera_id: str, turntable_deg: float) -> ReferenceRegion:
        """The laser's reference region of ``camera_id`` at ``turntable_deg`` (cached)."""
        key = (camera_id, round(float(turntable_deg), 6))
        with self._lock:
            region = self._regions.get(key)
        if region is None:
            holder = self.config.holder
            region = ReferenceRegion.from_holder(
                self.lens(camera_id, key[1]), sample_mm=holder.sample_mm, plate_mm=holder.plate_mm
            )
            with self._lock:
                self._regions[key] = region
        return region

    def ps_frames(self, view: View, step: int, image: np.ndarray) -> list[np.ndarray] | None:
        """Keep ``image`` (view ``view``'s frame of ``step``); the view's frames once ``step``
        is its last (those this worker was not sent read from the archive), else None.

        Frames of views that ended before ``step`` (another worker got their last
        frame) are dropped: a worker keeps about one view per camera.
        """
        last = max(view.steps)
        with self._lock:
            for key in [k for k, (end, _) in self._ps_frames.items() if end < step]:
                del self._ps_frames[key]
            self._ps_frames[(view.camera, step)] = (last, image)
            if step != last:
                return None
            kept = {s: self._ps_frames.pop((view.camera, s), (last, None))[1] for s in view.steps}
        missing = [s for s, frame in kept.items() if frame is None]
        if missing:
            with Archive.open(self.path, mode="r") as archive:
                kept.update({s: archive.read_frame(s, view.camera, 0) for s in missing})
        return [kept[s] for s in view.steps]


#: A worker's sessions by id, the most recent last.
_SESSIONS: OrderedDict[str, LiveSession] = OrderedDict()
_SESSIONS_LOCK = threading.Lock()
_KEPT_SESSIONS = 4


def _session_of(header: dict) -> LiveSession:
    if not header.get("archive"):
        raise ValueError("this live stage needs the session's archive path in the frame header")
    key = str(header["session"])
    with _SESSIONS_LOCK:
        session = _SESSIONS.get(key)
        if session is not None:
            _SESSIONS.move_to_end(key)
            return session
    session = LiveSession(header["archive"])
    with _SESSIONS_LOCK:
        session = _SESSIONS.setdefault(key, session)
        while len(_SESSIONS) > _KEPT_SESSIONS:
            _SESSIONS.popitem(last=False)
    return session


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


def live_laser_line(image: np.ndarray, header: dict) -> dict:
    """mdf frames → the laser line ``normal`` (2,), ``rho_mm``, ``reason``, ``inliers``."""
    if header["kind"] != "mdf":
        return {}
    session = _session_of(header)
    step = session.step(header["step"])
    turntable, arc = step.actuators["turntable_deg"], step.actuators["arc_deg"]
    region = session.region(header["camera"], turntable)
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
    view = session.ps_view_of(header["step"], header["camera"])
    if view is None or header["sub"] != 0:
        return {}
    frames = session.ps_frames(view, header["step"], image)
    if frames is None:
        return {}
    steps = [session.step(s) for s in view.steps]
    lens = session.lens(view.camera, view.turntable_deg)
    result = PsStage(size=size).solve(view, session.config, lens, steps, frames)
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
