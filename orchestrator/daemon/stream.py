"""Bookkeeping of the frames streamed to the workers: none is lost when a worker dies.

A PUSH socket hands each frame to one worker; if that worker dies the frame
is gone from ZeroMQ's queues. So every frame stays in the ledger until a
result carrying its ``frame_id`` comes back; a frame without a result after
``resend_after_s`` is sent again (to whichever worker is free). A late or
duplicate result of a frame already acknowledged is counted and ignored.
The ledger is used by the daemon's loop thread only (not thread-safe); the
``Outbox`` is how the session thread hands the loop its events, frames and drains
(a ``SessionOutbox``: what a session needs of the daemon, a list in tests).
"""

from __future__ import annotations

import queue
import threading
import time
from collections import OrderedDict, deque
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from orchestrator.wire.protocol import FrameHeader, encode_frame

__all__ = ["FrameLedger", "InFlight", "Outbox", "SessionOutbox"]


@dataclass
class InFlight:
    """One frame on its way: the message parts and when they last left."""

    frame_id: int
    session: str
    parts: list
    sent_at: float | None = None
    sends: int = 0


@dataclass
class FrameLedger:
    """Frames waiting to be sent (``pending``) or waiting for a result (``unacked``)."""

    resend_after_s: float = 10.0
    pending: deque[InFlight] = field(default_factory=deque)
    unacked: OrderedDict[int, InFlight] = field(default_factory=OrderedDict)
    acked: int = 0
    resent: int = 0
    duplicates: int = 0

    @property
    def in_flight(self) -> int:
        return len(self.pending) + len(self.unacked)

    def add(self, entry: InFlight) -> None:
        self.pending.append(entry)

    def next_to_send(self) -> InFlight | None:
        return self.pending[0] if self.pending else None

    def mark_sent(self, entry: InFlight, now: float) -> None:
        """``entry`` (the head of ``pending``) went out at ``now``."""
        self.pending.popleft()
        entry.sent_at = now
        entry.sends += 1
        if entry.sends > 1:
            self.resent += 1
        self.unacked[entry.frame_id] = entry
        self.unacked.move_to_end(entry.frame_id)

    def ack(self, frame_id: int) -> InFlight | None:
        """The frame's result arrived; None for an unknown or repeated id."""
        entry = self.unacked.pop(frame_id, None)
        if entry is None:
            # A resent frame may still sit in ``pending`` when its first result comes.
            for i, waiting in enumerate(self.pending):
                if waiting.frame_id == frame_id:
                    del self.pending[i]
                    entry = waiting
                    break
        if entry is None:
            self.duplicates += 1
            return None
        self.acked += 1
        return entry

    def requeue_overdue(self, now: float) -> int:
        """Move frames without a result for ``resend_after_s`` back to ``pending``."""
        overdue = []
        for entry in self.unacked.values():  # oldest first
            if now - entry.sent_at < self.resend_after_s:
                break
            overdue.append(entry)
        for entry in overdue:
            del self.unacked[entry.frame_id]
            self.pending.append(entry)
        return len(overdue)

    def outstanding(self, session: str) -> int:
        """Frames of ``session`` still without a result."""
        return sum(e.session == session for e in self.pending) + sum(
            e.session == session for e in self.unacked.values()
        )

    def forget(self, session: str) -> int:
        """Drop ``session``'s frames (no worker will process them live); how many."""
        kept = deque(e for e in self.pending if e.session != session)
        dropped = len(self.pending) - len(kept)
        self.pending = kept
        for frame_id in [f for f, e in self.unacked.items() if e.session == session]:
            del self.unacked[frame_id]
            dropped += 1
        return dropped


class SessionOutbox(Protocol):
    """Where a session's events and frames go (the daemon's sockets, or a list in tests)."""

    def publish(self, topic: str, payload: dict) -> None: ...
    def stream(self, header: FrameHeader, image: np.ndarray) -> None: ...
    def drain(self, session: str, timeout_s: float) -> int:
        """Wait for the session's outstanding results; for how many frames some were stored."""


class Outbox:
    """The session thread's side of the loop: events, frames (bounded) and drain requests."""

    def __init__(self, max_frames: int):
        self.events: queue.SimpleQueue = queue.SimpleQueue()
        self.frames: queue.Queue = queue.Queue(maxsize=max_frames)
        self.drains: queue.SimpleQueue = queue.SimpleQueue()

    def publish(self, topic: str, payload: dict) -> None:
        self.events.put((topic, payload))

    def stream(self, header: FrameHeader, image: np.ndarray) -> None:
        self.frames.put((header, encode_frame(header, image)))  # blocks while the loop is behind

    def drain(self, session: str, timeout_s: float) -> int:
        """Wait until the session's frames are processed (or ``timeout_s``); the number of
        live results stored in the archive."""
        done = threading.Event()
        request = {"session": session, "deadline": time.monotonic() + timeout_s, "done": done}
        self.drains.put(request)
        done.wait()
        return request["stored"]
