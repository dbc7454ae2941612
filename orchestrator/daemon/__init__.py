"""The orchestrator daemon: sessions over ZeroMQ, the state machine, devices, workers.

``Daemon`` (sockets and loop), ``Session`` (one plan against the devices and the
archive), ``RigDevices`` (the device facade). The messages are ``orchestrator.wire``'s;
``orchestrator.local`` runs the daemon for ``rig daemon`` and, with a client and workers,
for ``rig run``. See ``docs/daemon.md``.
"""

from orchestrator.daemon.devices import (
    Captured,
    DeviceSet,
    RigDevices,
    ThreadedCamera,
    build_devices,
)
from orchestrator.daemon.replay import ReplayDevices, replay_factory
from orchestrator.daemon.server import Daemon
from orchestrator.daemon.session import Session, SessionError, frame_formats
from orchestrator.daemon.state import (
    TRANSITIONS,
    IllegalTransition,
    SessionEvent,
    SessionState,
    StateMachine,
    allowed_events,
)

__all__ = [
    "TRANSITIONS",
    "Captured",
    "Daemon",
    "DeviceSet",
    "IllegalTransition",
    "ReplayDevices",
    "RigDevices",
    "Session",
    "SessionError",
    "SessionEvent",
    "SessionState",
    "StateMachine",
    "ThreadedCamera",
    "allowed_events",
    "build_devices",
    "frame_formats",
    "replay_factory",
]
