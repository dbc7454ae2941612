"""Entry points of ``rig daemon``, ``rig worker`` and ``rig run`` (daemon + submit + follow)."""

from __future__ import annotations

import logging
import signal
import threading
from collections.abc import Callable
from contextlib import contextmanager
from pathlib import Path

from orchestrator import client
from orchestrator.client import PREPARE_TIMEOUT_S, DaemonClient
from orchestrator.daemon.devices import build_devices
from orchestrator.daemon.replay import replay_factory
from orchestrator.daemon.server import Daemon
from orchestrator.daemon.session import DeviceFactory, SessionError
from orchestrator.wire.endpoints import DaemonSettings, Endpoints
from orchestrator.worker import run_worker, worker_stages
from rig.archive import Archive
from rig.clock import Clock
from rig.config import RigConfig, default_rig_config, load_rig_config

__all__ = ["daemon_thread", "replay_local", "run_daemon", "run_local"]

log = logging.getLogger(__name__)


def _rig_config(config: RigConfig | str | Path | None) -> RigConfig:
    """A config as given, read from its TOML path, or the default rig for None."""
    if config is None:
        return default_rig_config()
    return config if isinstance(config, RigConfig) else load_rig_config(config)


def run_daemon(
    config: RigConfig | str | Path | None,
    *,
    settings: DaemonSettings | None = None,
    on_ready: Callable[[Endpoints], None] | None = None,
) -> None:
    """Serve until ``shutdown`` or SIGINT/SIGTERM (``rig daemon --config RIG``).

    Must run on the main thread (it installs the signal handlers).
    """
    config = _rig_config(config)
    daemon = Daemon(config, settings=settings)
    endpoints = daemon.bind()
    previous = {
        sig: signal.signal(sig, lambda *_: daemon.stop()) for sig in (signal.SIGINT, signal.SIGTERM)
    }
    try:
        if on_ready is not None:
            on_ready(endpoints)
        daemon.serve()
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


@contextmanager
def daemon_thread(
    config: RigConfig,
    *,
    settings: DaemonSettings | None = None,
    devices: DeviceFactory = build_devices,
    clock: Clock | None = None,
):
    """A daemon serving on a thread of this process; yields its ``Endpoints``."""
    daemon = Daemon(config, settings=settings, devices=devices, clock=clock)
    endpoints = daemon.bind()
    thread = threading.Thread(target=daemon.serve, name="daemon-loop")
    thread.start()
    try:
        yield endpoints
    finally:
        daemon.stop()
        thread.join()


@contextmanager
def worker_threads(endpoints: Endpoints, stage: str, n: int):
    """``n`` workers of ``stage`` on threads of this process; ``ConfigError`` for an
    unknown stage before any starts (a worker thread's error would reach no one)."""

    worker_stages(stage)
    stop = threading.Event()
    threads = [
        threading.Thread(
            target=run_worker, args=(stage, endpoints), kwargs={"stop": stop}, name=f"worker-{i}"
        )
        for i in range(n)
    ]
    for t in threads:
        t.start()
    try:
        yield
    finally:
        stop.set()
        for t in threads:
            t.join()


def run_local(
    plan_path: str | Path,
    config: RigConfig | str | Path | None,
    *,
    archive: str | Path | None = None,
    workers: int = 1,
    stages: str = "stats",
    on_event: Callable[[dict], None] | None = None,
    devices: DeviceFactory = build_devices,
    clock: Clock | None = None,
    on_fault: str = "pause",
) -> dict:
    """Daemon + workers + submit + follow in one process; the final status (``rig run``).

    Every socket is on free loopback ports; ``workers`` threads run the live
    ``stages`` (comma-separated, see ``orchestrator.worker``); ``on_event`` sees each
    event (e.g. to draw a progress bar), first a ``daemon`` event with the ``control``
    address, where ``rig resume`` or ``rig abort --connect`` reach this run.
    ``on_fault``: ``"pause"`` (a person resumes the session) or ``"fail"`` (the run ends
    with the fault, for unattended runs).
    """
    def submit(endpoints: Endpoints) -> None:
        client.submit(plan_path, archive=archive, connect=endpoints)

    settings = DaemonSettings(port=0, on_fault=on_fault)
    return _in_process(
        _rig_config(config), submit, settings, devices, clock, workers, stages, on_event
    )


def replay_local(
    source: str | Path,
    *,
    out: str | Path,
    speed: float | None = None,
    workers: int = 1,
    on_event: Callable[[dict], None] | None = None,
    clock: Clock | None = None,
) -> dict:
    """Run the session recorded in ``source`` back through a daemon into ``out`` (``rig replay``).

    The plan and rig config come from the recording; the frames too (``ReplayDevices``).
    A mismatch between plan and recording fails the replay, naming the step.
    """

    with Archive.open(source, mode="r") as recording:
        plan_toml = recording.plan_toml
        config = RigConfig.model_validate(recording.rig_config)
    if plan_toml is None:
        raise SessionError(f"{source}: the archive holds no plan to replay")

    def submit(endpoints: Endpoints) -> None:
        with DaemonClient(endpoints, timeout_s=PREPARE_TIMEOUT_S) as control:  # it compiles
            control.request(
                "submit", plan_toml=plan_toml, source=f"replay of {source}",
                archive=str(Path(out).resolve()),
            )  # fmt: skip

    settings = DaemonSettings(port=0, on_fault="fail")
    devices = replay_factory(source, speed=speed)
    return _in_process(config, submit, settings, devices, clock, workers, "stats", on_event)


def _in_process(config, submit, settings, devices, clock, workers, stages, on_event) -> dict:
    daemon = daemon_thread(config, settings=settings, devices=devices, clock=clock)
    with daemon as endpoints, worker_threads(endpoints, stages, workers):
        if on_event is not None:  # where to send resume or abort while this run waits
            on_event({"topic": "daemon", "control": endpoints.control})
        submit(endpoints)
        for event in client.follow(endpoints, until=client.session_ended):
            if on_event is not None:
                on_event(event)
        return client.wait_for_state(endpoints, client.TERMINAL_STATES, settled=True, timeout_s=600)
