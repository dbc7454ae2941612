"""A session's progress: committed steps and frames, flagged frames, the fault in
hand, and the ETA.

The session thread advances it; the daemon's loop reads ``snapshot`` for the
``status`` reply at any time (a lock guards the counts). The ETA is the
schedule's estimate of the steps still to run, scaled by how fast the rig has
really been so far (elapsed clock time over the estimate of the steps done).
"""

from __future__ import annotations

import threading
import time

import numpy as np

from rig.archive import FrameFlag
from rig.frame_check import flag_summary
from rig.steps import Schedule, Step

__all__ = ["Progress"]


class Progress:
    """Counts of a session that resumes with ``committed`` steps and ``frames`` frames,
    ``flags`` of them flagged (step index, flag)."""

    def __init__(
        self,
        schedule: Schedule,
        *,
        committed: int,
        frames: int,
        flags: list[tuple[int, FrameFlag]] | None = None,
    ):
        self._schedule = schedule
        self._lock = threading.Lock()
        self._committed = committed
        self._frames = frames
        self._frames_before = frames  # a resumed session's rate counts its own
        self._flags = list(flags or ())
        self._step_index: int | None = None
        self._fault: dict | None = None
        self._reason: str | None = None
        self._per_kind_s = _per_step_estimate(schedule)
        # Estimated time of the steps after each step, for the ETA.
        per_step = [self._per_kind_s[s.kind] for s in schedule.steps]
        self._remaining_after = np.cumsum(per_step[::-1])[::-1] - np.array(per_step)
        self._t0 = (0.0, 0.0)
        self._done_estimate_s = 0.0

    def snapshot(self) -> dict:
        """Committed steps, the step in hand, frames, flagged frames
        (``rig.frame_check.flag_summary``), fault and failure reason (thread-safe)."""
        with self._lock:
            return {
                "committed": self._committed,
                "step_index": self._step_index,
                "frames": self._frames,
                "flagged": flag_summary(self._flags),
                "fault": self._fault,
                "reason": self._reason,
            }

    def started(self, clock_now: float) -> None:
        """The rig is homed and the first step begins at ``clock_now`` (the session's clock)."""
        self._t0 = (clock_now, time.perf_counter())
        self._done_estimate_s = 0.0

    def at_step(self, index: int) -> None:
        with self._lock:
            self._step_index = index

    def set_fault(self, fault: dict | None) -> None:
        """The fault that paused the session (device, operation, detail, step); None: cleared."""
        with self._lock:
            self._fault = fault

    def set_reason(self, reason: str) -> None:
        """Why the session failed."""
        with self._lock:
            self._reason = reason

    def step_done(
        self, step: Step, n_frames: int, clock_now: float, *, flags: tuple[FrameFlag, ...] = ()
    ) -> dict:
        """Count a committed step of ``n_frames`` frames, ``flags`` of them flagged;
        the ``progress`` event's payload."""
        with self._lock:
            self._committed += 1
            self._frames += n_frames
            self._flags += [(step.index, flag) for flag in flags]
            committed, frames = self._committed, self._frames
        self._done_estimate_s += self._per_kind_s[step.kind]
        clock_elapsed = clock_now - self._t0[0]
        remaining = float(self._remaining_after[step.index])
        # Scale the estimate by how fast the rig has really been so far.
        pace = clock_elapsed / self._done_estimate_s if self._done_estimate_s > 0 else 1.0
        return {
            "step": committed,
            "steps": len(self._schedule.steps),
            "step_index": step.index,
            "kind": step.kind,
            "eta_s": remaining * pace,
            "elapsed_s": clock_elapsed,
            "wall_s": time.perf_counter() - self._t0[1],
            "frames": frames,
            "frames_per_s": (
                (frames - self._frames_before) / clock_elapsed if clock_elapsed > 0 else 0.0
            ),
        }


def _per_step_estimate(schedule: Schedule) -> dict[str, float]:
    counts: dict[str, int] = {}
    for step in schedule.steps:
        counts[step.kind] = counts.get(step.kind, 0) + 1
    return {k: schedule.estimate.by_kind_s.get(k, 0.0) / n for k, n in counts.items()}
