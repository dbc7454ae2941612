"""A laser scan: the sheet sweeps, each frame waits for its tilt and is checked.

``sweep_scan`` drives one sweep of the sheet for ``RigDevices.scan``. The frames
are paced by the tilt motor's read-back (``_Sweep``), not by the clock: the
sheet's real speed (a battery, a gearbox, a simulator run faster than the
daemon's clock) decides when a frame is due. Every frame is checked against its
planned tilt (``rig.frame_check``); one the sheet ran away from is taken again
with the sheet held at its tilt, and flagged.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from drivers.interfaces import Axis
from rig.archive import FrameFlag
from rig.clock import Clock
from rig.config import Laser, RigConfig
from rig.frame_check import (
    FrameState,
    frame_mismatch,
    scan_tilts_deg,
    stale_frames,
    tilt_tolerance_deg,
)

__all__ = ["Captured", "Scan", "sweep_scan"]


@dataclass(frozen=True)
class Captured:
    """One frame as the session stores it."""

    image: np.ndarray
    sub: int
    exposure_s: float
    timestamp: float


@dataclass(frozen=True)
class Scan:
    """A laser scan as the session stores it: the frames per camera, the tilt (deg)
    read back at each frame, and the frames that did not match their planned tilt."""

    frames: dict[str, list[Captured]]
    tilts_deg: list[float]
    flags: tuple[FrameFlag, ...] = ()


#: ``shoot(cameras, exposure_s, sub, into)``: trigger the cameras together, append to ``into``.
Shoot = Callable[[Sequence[str], float, int, dict], None]


def sweep_scan(
    tilt: Axis,
    config: RigConfig,
    clock: Clock,
    cameras: Sequence[str],
    *,
    tilt_deg: tuple[float, float],
    frames: int,
    exposure_s: float,
    shoot: Shoot,
    hold: Callable[[float], float],
) -> Scan:
    """Sweep ``tilt`` from where it stands (``tilt_deg[0]``) to ``tilt_deg[1]``.

    ``hold(deg)`` moves the sheet to ``deg`` and waits (the tilt read back); the
    sheet is left where the last frame needed it. See ``RigDevices.scan``.
    """
    planned = scan_tilts_deg(config, tilt_deg, frames)
    tolerance = tilt_tolerance_deg(config, planned)
    captured: dict[str, list[Captured]] = {c: [] for c in cameras}
    readbacks = []
    tilt.move_to(tilt_deg[1])
    sweep = _Sweep(tilt, clock, end_deg=tilt_deg[1], laser=config.laser)
    for sub, target in enumerate(planned):
        before = sweep.reach(float(target))
        shoot(cameras, exposure_s, sub, captured)
        readbacks.append((before, float(tilt.position())))
    tilt.wait_until_settled()
    reasons = _scan_mismatches(planned, readbacks, captured, tolerance)
    flags = []
    for sub in sorted(reasons, reverse=True):  # back from the sweep's end: short moves
        held = hold(float(planned[sub]))
        again: dict[str, list[Captured]] = {c: [] for c in cameras}
        shoot(cameras, exposure_s, sub, again)
        readbacks[sub] = (held, float(tilt.position()))
        still = frame_mismatch(
            FrameState(tilt_deg=float(planned[sub])),
            [FrameState(tilt_deg=t) for t in readbacks[sub]],
            tilt_tolerance_deg=tolerance,
        )
        for camera in cameras:  # every camera's frame is the re-take; the failed ones flagged
            captured[camera][sub] = again[camera][0]
            if camera in reasons[sub]:
                reason = reasons[sub][camera]
                if still is not None:
                    reason = f"{reason}; taken again at a held tilt: {still}"
                flags.append(FrameFlag(camera, sub, reason, recaptured=still is None))
    flags.sort(key=lambda flag: (flag.sub, flag.camera))
    return Scan(captured, [before for before, _ in readbacks], tuple(flags))


def _scan_mismatches(
    planned: np.ndarray,
    readbacks: Sequence[tuple[float, float]],
    captured: Mapping[str, Sequence[Captured]],
    tolerance_deg: float,
) -> dict[int, dict[str, str]]:
    """Why each scan frame (by sub, then camera) does not record its planned tilt."""
    reasons: dict[int, dict[str, str]] = {}
    for sub, (target, around) in enumerate(zip(planned, readbacks, strict=True)):
        why = frame_mismatch(
            FrameState(tilt_deg=float(target)), [FrameState(tilt_deg=t) for t in around],
            tilt_tolerance_deg=tolerance_deg,
        )  # fmt: skip
        if why is not None:
            reasons[sub] = {camera: why for camera in captured}
    for camera, frames in captured.items():
        for sub, why in stale_frames([f.timestamp for f in frames]).items():
            reasons.setdefault(sub, {})[camera] = why
    return reasons


class _Sweep:
    """Paces a sweep's frames by the sheet's read-back, not by the clock.

    ``reach`` waits until the tacho count says the sheet reached a tilt, and
    at least a laser frame period (``frame_rate_hz``) after the frame before. It
    sleeps for the distance left at the speed the sheet has shown so far (never
    less than the configured one): a sheet faster than its config, or a clock
    slower than the sheet's (a simulator run sped up), does not make it wait
    past the crossing.
    """

    def __init__(self, tilt: Axis, clock: Clock, *, end_deg: float, laser: Laser):
        self.tilt = tilt
        self.clock = clock
        self.end_deg = end_deg
        self.speed_deg_s = self.planned_deg_s = laser.sweep_speed_deg_s
        self.count_deg = laser.device.gear_ratio  # one tacho count: the read-back's resolution
        self.period_s = 1.0 / laser.frame_rate_hz
        self._last: tuple[float, float] | None = None  # (time, tilt) of the last read
        self._timeout_at: float | None = None
        self._not_before: float | None = None

    def reach(self, target_deg: float) -> float:
        """The tilt read back once the sheet is within half a count of ``target_deg``
        (or has stopped, or twice the planned sweep time passed)."""
        direction = 1.0 if self.end_deg >= target_deg else -1.0
        if self._not_before is not None:
            self.clock.sleep(max(0.0, self._not_before - self.clock.now()))
        if self._timeout_at is None:
            sweep_s = abs(self.end_deg - float(self.tilt.position())) / self.speed_deg_s
            self._timeout_at = self.clock.now() + 2.0 * sweep_s + 1.0
        while True:
            t, deg = self.clock.now(), float(self.tilt.position())
            stopped = False
            if self._last is not None and t > self._last[0]:
                shown = abs(deg - self._last[1]) / (t - self._last[0])
                self.speed_deg_s = max(self.speed_deg_s, shown)
                # no new count in the time a count takes at the planned speed
                idle_s = t - self._last[0]
                stopped = deg == self._last[1] and idle_s * self.planned_deg_s >= self.count_deg
            self._last = (t, deg)
            remaining = direction * (target_deg - deg)
            # the count is rounded: a sheet at the target reads within half a count
            if remaining <= 0.5 * self.count_deg + 1e-9 or stopped or t > self._timeout_at:
                self._not_before = t + self.period_s
                return deg
            self.clock.sleep(remaining / self.speed_deg_s)
