"""Injectable time: the same code runs in real time on a rig and in virtual
time in tests and the simulator (a two-hour session replays in seconds)."""

from __future__ import annotations

import threading
import time
from collections.abc import Hashable, Iterator
from contextlib import AbstractContextManager, contextmanager, nullcontext
from typing import Protocol

__all__ = ["Clock", "RealClock", "ScaledClock", "VirtualClock"]


class Clock(Protocol):
    def now(self) -> float:
        """Seconds since an arbitrary epoch."""

    def sleep(self, seconds: float) -> None:
        """Let ``seconds`` pass."""

    def parallel(self) -> AbstractContextManager[None]:
        """A section in which devices work at once (cameras triggered together).

        Real time needs nothing: concurrent waits overlap by themselves.
        """

    def lane(self, key: Hashable) -> AbstractContextManager[None]:
        """Mark the waits inside as one device's (``key``), for a thread serving several."""


class RealClock:
    """Wall-clock time (monotonic)."""

    def now(self) -> float:
        return time.monotonic()

    def sleep(self, seconds: float) -> None:
        if seconds > 0:
            time.sleep(seconds)

    def parallel(self) -> AbstractContextManager[None]:
        return nullcontext()

    def lane(self, key: Hashable) -> AbstractContextManager[None]:
        return nullcontext()


class ScaledClock(RealClock):
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

    Thread-safe. Outside a :meth:`parallel` section the sleeps of all threads
    add up (one thing happens at a time: a plan's steps, a driver's polling).
    Inside one, every *lane* — a thread, or a ``lane(key)`` a thread serves —
    starts at the section's start and keeps its own time; the clock stands at
    the latest lane, and leaves the section there. Eight cameras triggered
    together each sleeping exposure + readout advance the clock by that once.
    """

    def __init__(self, start: float = 0.0):
        self._now = float(start)
        self._lock = threading.Lock()
        self._depth = 0  # nested parallel sections count as the outermost one
        self._fork = 0.0
        self._lanes: dict[Hashable, float] = {}
        self._local = threading.local()

    def _key(self) -> Hashable:
        lanes = self._local.__dict__.setdefault("lanes", [])
        if lanes:
            return lanes[-1]
        # A token per thread, not its ident: a finished thread's ident is reused.
        return self._local.__dict__.setdefault("thread", object())

    def now(self) -> float:
        with self._lock:
            if self._depth:
                return self._lanes.get(self._key(), self._fork)
            return self._now

    def sleep(self, seconds: float) -> None:
        if seconds < 0:
            raise ValueError(f"VirtualClock.sleep: seconds={seconds} must be ≥ 0")
        with self._lock:
            if self._depth:
                key = self._key()
                self._lanes[key] = self._lanes.get(key, self._fork) + seconds
                self._now = max(self._now, self._lanes[key])
            else:
                self._now += seconds

    def advance_to(self, t: float) -> None:
        """Jump forward to ``t`` (never backwards)."""
        with self._lock:
            self._now = max(self._now, float(t))

    @contextmanager
    def parallel(self) -> Iterator[None]:
        with self._lock:
            if self._depth == 0:
                self._fork, self._lanes = self._now, {}
            self._depth += 1
        try:
            yield
        finally:
            with self._lock:
                self._depth -= 1

    @contextmanager
    def lane(self, key: Hashable) -> Iterator[None]:
        lanes = self._local.__dict__.setdefault("lanes", [])
        lanes.append(("lane", key))
        try:
            yield
        finally:
            lanes.pop()
