"""Injectable time: the same code runs in real time on a rig and in virtual
time in tests and the simulator (a two-hour session replays in seconds)."""

from __future__ import annotations

import threading
import time
from typing import Protocol

__all__ = ["Clock", "RealClock", "ScaledClock", "VirtualClock"]


class Clock(Protocol):
    def now(self) -> float:
        """Seconds since an arbitrary epoch."""

    def sleep(self, seconds: float) -> None:
        """Let ``seconds`` pass."""


class RealClock:
    """Wall-clock time (monotonic)."""

    def now(self) -> float:
        return time.monotonic()

    def sleep(self, seconds: float) -> None:
        if seconds > 0:
            time.sleep(seconds)


class ScaledClock:
    """Real time sped up ``speed`` times: a simulated rig in another process
    (``rig sim --speed N``) finishes a modelled 10 s move in 10/N s of wall time."""

    def __init__(self, speed: float = 1.0):
        if not speed > 0:
            raise ValueError(f"ScaledClock: speed={speed} must be > 0")
        self.speed = float(speed)
        self._start = time.monotonic()

    def now(self) -> float:
        return (time.monotonic() - self._start) * self.speed

    def sleep(self, seconds: float) -> None:
        if seconds > 0:
            time.sleep(seconds / self.speed)


class VirtualClock:
    """Time that advances only when someone sleeps: sleeping returns at once.

    Thread-safe; several threads sleeping advance one shared time, which is
    the sum of sleeps — good enough for sequential plans and device peers.
    """

    def __init__(self, start: float = 0.0):
        self._now = float(start)
        self._lock = threading.Lock()

    def now(self) -> float:
        with self._lock:
            return self._now

    def sleep(self, seconds: float) -> None:
        if seconds < 0:
            raise ValueError(f"VirtualClock.sleep: seconds={seconds} must be ≥ 0")
        with self._lock:
            self._now += seconds

    def advance_to(self, t: float) -> None:
        """Jump forward to ``t`` (never backwards)."""
        with self._lock:
            self._now = max(self._now, float(t))
