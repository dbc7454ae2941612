"""The session state machine: one explicit table of legal transitions.

::

    idle ─submit→ homing ─homed→ running ⇄ paused        (pause / resume, fault)
                                    └─steps_done→ finishing ─finished→ done
    homing, running, paused ─abort→ aborted;  any active state ─fail→ failed
    done | aborted | failed ─submit→ homing                (the next session)

A ``fault`` (a device error that survived the driver's retries) pauses the
session; ``resume`` retries the step that failed. Every event that the table
does not list for the current state raises ``IllegalTransition`` naming the
state and the events that are allowed there.
"""

from __future__ import annotations

import enum
import threading
from collections.abc import Callable

from rig.errors import RigError

__all__ = ["TRANSITIONS", "IllegalTransition", "SessionEvent", "SessionState", "StateMachine"]


class SessionState(enum.StrEnum):
    IDLE = "idle"
    HOMING = "homing"
    RUNNING = "running"
    PAUSED = "paused"
    FINISHING = "finishing"
    DONE = "done"
    ABORTED = "aborted"
    FAILED = "failed"

    @property
    def active(self) -> bool:
        """A session holds the devices in this state."""
        return self in _ACTIVE

    @property
    def terminal(self) -> bool:
        return self in (SessionState.DONE, SessionState.ABORTED, SessionState.FAILED)


_ACTIVE = frozenset(
    {SessionState.HOMING, SessionState.RUNNING, SessionState.PAUSED, SessionState.FINISHING}
)


class SessionEvent(enum.StrEnum):
    SUBMIT = "submit"
    HOMED = "homed"
    PAUSE = "pause"
    FAULT = "fault"
    RESUME = "resume"
    STEPS_DONE = "steps_done"
    FINISHED = "finished"
    ABORT = "abort"
    FAIL = "fail"


S, E = SessionState, SessionEvent

#: (state, event) → next state; nothing else is legal.
TRANSITIONS: dict[tuple[SessionState, SessionEvent], SessionState] = {
    (S.IDLE, E.SUBMIT): S.HOMING,
    (S.DONE, E.SUBMIT): S.HOMING,
    (S.ABORTED, E.SUBMIT): S.HOMING,
    (S.FAILED, E.SUBMIT): S.HOMING,
    (S.HOMING, E.HOMED): S.RUNNING,
    (S.HOMING, E.ABORT): S.ABORTED,
    (S.HOMING, E.FAIL): S.FAILED,
    (S.RUNNING, E.PAUSE): S.PAUSED,
    (S.RUNNING, E.FAULT): S.PAUSED,
    (S.RUNNING, E.STEPS_DONE): S.FINISHING,
    (S.RUNNING, E.ABORT): S.ABORTED,
    (S.RUNNING, E.FAIL): S.FAILED,
    (S.PAUSED, E.RESUME): S.RUNNING,
    (S.PAUSED, E.ABORT): S.ABORTED,
    (S.PAUSED, E.FAIL): S.FAILED,
    (S.FINISHING, E.FINISHED): S.DONE,
    (S.FINISHING, E.FAIL): S.FAILED,
}

del S, E


class IllegalTransition(RigError):
    """An event that the current state does not accept."""

    def __init__(self, state: SessionState, event: SessionEvent | str):
        self.state = state
        self.event = str(event)
        self.allowed = allowed_events(state)
        allowed = ", ".join(self.allowed) or "none"
        super().__init__(
            f"'{self.event}' is not possible while the session is {state.value}; "
            f"allowed now: {allowed}"
        )


def allowed_events(state: SessionState) -> tuple[str, ...]:
    """The events the table accepts in ``state``, in table order."""
    return tuple(str(event) for (s, event) in TRANSITIONS if s == state)


class StateMachine:
    """The current state and its legal moves; thread-safe.

    ``on_change(old, new, event, detail)`` is called after each transition
    (outside the lock), e.g. to publish it.
    """

    def __init__(
        self,
        state: SessionState = SessionState.IDLE,
        *,
        on_change: Callable[[SessionState, SessionState, SessionEvent, dict], None] | None = None,
    ):
        self._state = state
        self._lock = threading.Lock()
        self._on_change = on_change

    @property
    def state(self) -> SessionState:
        with self._lock:
            return self._state

    def can(self, event: SessionEvent | str) -> bool:
        with self._lock:
            return (self._state, SessionEvent(event)) in TRANSITIONS

    def fire(self, event: SessionEvent | str, **detail) -> SessionState:
        """Take the transition for ``event``; raise ``IllegalTransition`` if there is none."""
        try:
            event = SessionEvent(event)
        except ValueError:
            raise IllegalTransition(self.state, event) from None
        with self._lock:
            old = self._state
            new = TRANSITIONS.get((old, event))
            if new is None:
                raise IllegalTransition(old, event)
            self._state = new
        if self._on_change is not None:
            self._on_change(old, new, event, detail)
        return new
