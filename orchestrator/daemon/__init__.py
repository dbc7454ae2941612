"""The orchestrator daemon: sessions over ZeroMQ, the state machine, devices, workers.

``Daemon`` (sockets and loop), ``Session`` (one plan against the devices and the
archive), ``RigDevices`` (the device facade) and the message ``protocol``;
``run_daemon`` and ``run_local`` are what ``rig daemon`` and ``rig run`` call.
See ``docs/daemon.md``.
"""

from orchestrator.daemon.devices import (
    Captured,
    DeviceSet,
    RigDevices,
    ThreadedCamera,
    build_devices,
)
from orchestrator.daemon.endpoints import (
    DEFAULT_PORT,
    ClientKeys,
    DaemonSettings,
    Endpoints,
    is_loopback,
)
from orchestrator.daemon.local import daemon_thread, replay_local, run_daemon, run_local
from orchestrator.daemon.protocol import MessageError
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
    "DEFAULT_PORT",
    "TRANSITIONS",
    "Captured",
    "ClientKeys",
    "Daemon",
    "DaemonSettings",
    "DeviceSet",
    "Endpoints",
    "IllegalTransition",
    "MessageError",
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
    "daemon_thread",
    "frame_formats",
    "is_loopback",
    "replay_factory",
    "replay_local",
    "run_daemon",
    "run_local",
]
