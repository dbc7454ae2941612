"""The state machine: every legal transition, every other event rejected with the allowed ones."""

import threading

import pytest

from orchestrator.daemon.state import (
    TRANSITIONS,
    IllegalTransition,
    SessionEvent,
    SessionState,
    StateMachine,
    allowed_events,
)

ALL_PAIRS = [(s, e) for s in SessionState for e in SessionEvent]


@pytest.mark.parametrize(("state", "event"), list(TRANSITIONS))
def test_legal_transition(state, event):
    seen = []
    machine = StateMachine(state, on_change=lambda *a: seen.append(a))
    new = machine.fire(event, reason="x")
    assert new == TRANSITIONS[(state, event)] == machine.state
    assert seen == [(state, new, event, {"reason": "x"})]


@pytest.mark.parametrize(("state", "event"), [p for p in ALL_PAIRS if p not in TRANSITIONS])
def test_illegal_transition_names_state_and_allowed(state, event):
    machine = StateMachine(state)
    with pytest.raises(IllegalTransition) as info:
        machine.fire(event)
    assert machine.state == state
    assert info.value.allowed == allowed_events(state)
    assert state.value in str(info.value) and event.value in str(info.value)
    for allowed in info.value.allowed:
        assert allowed in str(info.value)


def test_unknown_event_is_illegal():
    with pytest.raises(IllegalTransition, match="'jump' is not possible while the session is idle"):
        StateMachine().fire("jump")


def test_the_designed_paths():
    machine = StateMachine()
    path = ["submit", "homed", "pause", "resume", "fault", "resume", "steps_done", "finished"]
    states = [machine.fire(e).value for e in path]
    assert states == [
        "homing", "running", "paused", "running", "paused", "running", "finishing", "done"
    ]  # fmt: skip
    assert machine.fire("submit") == SessionState.HOMING  # the next session


def test_terminal_states_only_accept_a_new_session():
    for state in SessionState:
        if state.terminal:
            assert allowed_events(state) == ("submit",)
    assert allowed_events(SessionState.FINISHING) == ("finished", "fail")


def test_concurrent_fires_take_exactly_one_transition():
    machine = StateMachine(SessionState.RUNNING)
    wins, losses = [], []
    barrier = threading.Barrier(8)

    def fire():
        barrier.wait()
        try:
            wins.append(machine.fire("pause"))
        except IllegalTransition:
            losses.append(1)

    threads = [threading.Thread(target=fire) for _ in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert len(wins) == 1 and len(losses) == 7
