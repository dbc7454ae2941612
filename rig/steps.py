"""What a compiled plan is: steps, each carrying its rig kind's pose, and the estimate.

Every rig kind compiles a plan (``RigKind.compile``) into the same ``Schedule``
of ``Step``s; what differs is the step's ``pose``, the kind's payload saying
where its actuators go (``AxesPose`` for a Wang rig or a VirTex stage, the Bonn
lab's ``rig.bonn_plan.ArmRailPose``). The daemon hands the pose to the kind's
device set and the kind's kinematics read it back into directions; nothing
else looks inside.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, NamedTuple

from rig.config import RigConfig
from rig.plan import Plan

__all__ = ["AxesPose", "Estimate", "Schedule", "Shot", "Step", "frame_bytes", "wanted_pairs"]


class AxesPose(NamedTuple):
    """A Wang rig's (or a VirTex stage's, both 0) turntable and light-arc angles (deg)."""

    turntable_deg: float
    arc_deg: float

    #: The read-backs a step's frames must still show after capture (``checks``).
    checked_axes = ("turntable_deg", "arc_deg")

    def summary(self) -> str:
        """One line for a table of steps."""
        return f"turntable {self.turntable_deg:.1f}°, arc {self.arc_deg:.1f}°"


@dataclass(frozen=True)
class Shot:
    """What one camera records in a step, in the sample frame (degrees)."""

    camera: str
    view_deg: tuple[float, float]
    light_deg: tuple[float, float]
    view_residual_deg: float
    light_residual_deg: float


@dataclass(frozen=True)
class Step:
    """One idempotent unit of work: move → settle → lamp/laser → capture → commit.

    ``kind`` is the capture (``ps``, ``btf``, ``mdf``); ``pose`` the rig kind's
    actuator targets. ``exposures_s`` holds one exposure per frame for lamp steps
    (HDR brackets); a laser step records ``scan_frames`` frames per camera at the
    laser exposure while the sheet tilts from ``tilt_deg[0]`` to ``tilt_deg[1]``.
    """

    index: int
    kind: str
    pose: Any
    source: str
    shots: tuple[Shot, ...]
    exposures_s: tuple[float, ...]
    scan_frames: int = 0
    tilt_deg: tuple[float, float] | None = None

    @property
    def cameras(self) -> tuple[str, ...]:
        return tuple(s.camera for s in self.shots)

    @property
    def frames_per_camera(self) -> int:
        return self.scan_frames if self.kind == "mdf" else len(self.exposures_s)


@dataclass(frozen=True)
class Estimate:
    """Expected duration (s) and data size (bytes) of a schedule."""

    total_s: float
    motion_s: float
    lamp_s: float
    capture_s: float
    frames: int
    bytes: int
    by_kind_s: dict[str, float]


@dataclass(frozen=True)
class Schedule:
    steps: tuple[Step, ...]
    estimate: Estimate
    naive_estimate: Estimate
    max_view_residual_deg: float
    max_light_residual_deg: float
    pairs: int = field(default=0)


def _pairs(kind: str, views, lights):
    for v in views.resolve().directions:
        for light in lights.resolve().directions:
            yield kind, (float(v[0]), float(v[1])), (float(light[0]), float(light[1]))


def wanted_pairs(plan: Plan):
    """(capture kind, view, light) in the plan's own order."""
    c = plan.captures
    if c.ps is not None:
        yield from _pairs("ps", c.ps.views, c.ps.lights)
    if c.btf is not None:
        yield from _pairs("btf", c.btf.views, c.btf.lights)
    if c.mdf is not None:
        yield from _pairs("mdf", c.mdf.views, c.mdf.laser_locations)


def frame_bytes(config: RigConfig, camera_id: str, scale: float) -> int:
    """Bytes of one frame of ``camera_id`` at the plan's resolution ``scale``."""
    cam = config.camera(camera_id)
    w, h = max(1, round(cam.width * scale)), max(1, round(cam.height * scale))
    return w * h * cam.channels * (1 if cam.bit_depth == 8 else 2)
