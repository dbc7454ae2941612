"""Shared by the integration tests: a small fast scene and a session runner."""

from __future__ import annotations

import tomllib
from pathlib import Path

import pytest

from orchestrator import client
from orchestrator.local import daemon_thread, worker_threads
from orchestrator.wire.endpoints import DaemonSettings
from sim.scene import scene_from_dict

PLAN = """
[sample]
name = "integration"
[captures.ps]
lights = {theta_deg = 45, count = 3}
[captures.btf]
views = [[0, 0], [30, 90]]
lights = [[45, 0], [30, 180]]
[captures.mdf]
views = [[0, 0]]
laser_locations = [[45, 0]]
scan_step_deg = 4.0
"""


@pytest.fixture(scope="module")
def scene():
    path = Path("examples/scenes/bumps.toml")
    data = tomllib.loads(path.read_text())
    data["render"]["scale"] = 0.2  # 1/5 of the rig's sensor: fast, still every feature
    return scene_from_dict(data, source=str(path), base_dir=path.parent)


def run_session(sim, clock, tmp_path, plan=PLAN, *, until_state=client.TERMINAL_STATES, act=None):
    """Run ``plan`` to ``until_state``; ``act(endpoints, status)`` may then steer it on."""
    (tmp_path / "plan.toml").write_text(plan)
    archive = tmp_path / "session.zarr"
    settings = DaemonSettings(port=0)
    with (
        daemon_thread(sim.rig_config(), settings=settings, clock=clock) as endpoints,
        worker_threads(endpoints, "stats", 1),
    ):
        client.submit(tmp_path / "plan.toml", archive=archive, connect=endpoints)
        # a paused session keeps the devices: only a finished one settles
        settled = set(until_state) <= set(client.TERMINAL_STATES)
        status = client.wait_for_state(endpoints, until_state, settled=settled, timeout_s=60)
        if act is not None:
            status = act(endpoints, status)
    return archive, status
