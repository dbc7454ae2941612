"""Fixtures of the daemon tests: a small rig, a tiny plan, soft devices, a running daemon."""

from __future__ import annotations

import threading
from contextlib import contextmanager

import pytest

from orchestrator.daemon import Daemon
from orchestrator.wire.endpoints import DaemonSettings
from orchestrator.worker import run_worker
from rig.clock import VirtualClock
from rig.config import default_rig_config
from tests.orchestrator.daemon.soft import SoftRig, soft_devices

TINY_PLAN = """
[sample]
name = "tiny"
[captures.btf]
views = [[0, 0], [30, 0]]
lights = {theta_deg = 45, count = 4}
[captures.mdf]
views = [[0, 0]]
laser_locations = [[45, 0]]
scan_step_deg = 2.0
[exposure]
hdr_brackets = [1.0, 2.0]
[resolution]
scale = 0.0625
"""

#: Lamp steps only, more of them (for pause/abort/fault tests).
LAMP_PLAN = """
[sample]
name = "lamps"
[captures.btf]
views = [[0, 0], [30, 0], [30, 90]]
lights = {theta_deg = 45, count = 6}
[resolution]
scale = 0.0625
"""


@pytest.fixture
def config():
    return default_rig_config()


@pytest.fixture
def rig(config):
    return SoftRig(config, VirtualClock())


@contextmanager
def running_daemon(config, rig: SoftRig, **settings):
    """A daemon on free loopback ports serving in a thread; stopped and joined on exit."""
    options = {"port": 0, "status_interval_s": 0.2, "drain_timeout_s": 5.0, **settings}
    daemon = Daemon(
        config, settings=DaemonSettings(**options), devices=soft_devices(rig), clock=rig.clock
    )
    endpoints = daemon.bind()
    thread = threading.Thread(target=daemon.serve, name="daemon-loop")
    thread.start()
    try:
        yield endpoints
    finally:
        daemon.stop()
        thread.join(30)
        assert not thread.is_alive(), "the daemon loop did not stop"


@contextmanager
def running_workers(endpoints, n: int = 2, stage: str = "stats"):
    """``n`` workers in threads; stopped and joined on exit."""
    stop = threading.Event()
    counts: dict[str, int] = {}

    def work(name):
        counts[name] = run_worker(stage, endpoints, stop=stop, name=name, heartbeat_s=0.1)

    threads = [threading.Thread(target=work, args=(f"w{i}",), name=f"worker-{i}") for i in range(n)]
    for t in threads:
        t.start()
    try:
        yield counts
    finally:
        stop.set()
        for t in threads:
            t.join(10)
