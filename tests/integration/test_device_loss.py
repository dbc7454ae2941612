"""Every device vanishes mid-session, as when the simulated rig's process is killed: the
session pauses naming a device (it does not fail), and once the rig is back on other
ports, `resume ARCHIVE --config NEW-RIG` finishes it with every step once."""

from __future__ import annotations

import signal
import time
import tomllib

import pytest
import tomli_w

from orchestrator import client
from orchestrator.local import daemon_thread, worker_threads
from orchestrator.wire.endpoints import DaemonSettings
from rig.archive import Archive
from rig.clock import VirtualClock
from rig.config import write_rig_config
from sim.rig import SimulatedRig
from tests.integration.conftest import PLAN
from tests.integration.test_cli_processes import PLAN as CLI_PLAN
from tests.integration.test_cli_processes import (
    ROOT,
    _cli,
    _free_base_port,
    _start,
    _stop,
    _wait,
    _wait_up,
)

# Sessions, subprocesses or benches: the full tier only (make test), not make quick.
pytestmark = pytest.mark.slow


def _committed(connect) -> int:
    return (client.status(connect=connect)["session"] or {}).get("committed", 0)


def test_a_vanished_rig_pauses_naming_a_device_and_resumes_on_new_ports(scene, tmp_path):
    clock = VirtualClock()
    plan, archive = tmp_path / "plan.toml", tmp_path / "session.zarr"
    plan.write_text(PLAN)
    sim = SimulatedRig(scene, clock=clock).start()
    try:
        daemon = daemon_thread(sim.rig_config(), settings=DaemonSettings(port=0), clock=clock)
        with daemon as endpoints, worker_threads(endpoints, "stats", 1):
            client.submit(plan, archive=archive, connect=endpoints)
            deadline = time.monotonic() + 60
            while _committed(endpoints) < 1:
                assert time.monotonic() < deadline, "no step committed"
                time.sleep(0.01)
            sim.stop()  # every peer goes at once
            paused = client.wait_for_state(
                endpoints, ("paused", *client.TERMINAL_STATES), timeout_s=120
            )
            assert paused["state"] == "paused", paused["session"]
            fault = paused["session"]["fault"]
            assert fault["device"] and fault["step"] == paused["session"]["step_index"], fault
            assert client.abort(connect=endpoints)["state"] == "aborted"

            sim = SimulatedRig(scene, clock=clock).start()  # back, on other ports
            moved = write_rig_config(sim.rig_config(), tmp_path / "rig-now.toml")
            client.resume(archive, config=moved, connect=endpoints)
            final = client.wait_for_state(
                endpoints, client.TERMINAL_STATES, settled=True, timeout_s=120
            )
    finally:
        sim.stop()
    assert final["state"] == "done", final["session"]
    with Archive.open(archive) as arch:
        committed = arch.committed_steps()
        table = arch.frame_table()
        faults = [e.payload for e in arch.events("fault")]
    assert committed == tuple(range(final["session"]["steps"]))
    keys = [(int(r["step"]), str(r["camera"]), int(r["sub"])) for r in table]
    assert len(keys) == len(set(keys)) == final["session"]["frames"]  # nothing twice
    assert faults and faults[0]["device"] == fault["device"]


def test_kill_9_of_rig_sim_pauses_and_rig_resume_config_finishes(tmp_path):
    """The same on the command line: `rig sim` SIGKILLed mid-session, started again on
    new ports, `rig abort`, `rig resume ARCHIVE --config NEW-RIG`."""
    scene = tomllib.loads((ROOT / "examples/scenes/bumps.toml").read_text())
    scene["render"]["scale"] = 0.2
    (tmp_path / "scene.toml").write_text(tomli_w.dumps(scene))
    (tmp_path / "plan.toml").write_text(CLI_PLAN)
    archive = tmp_path / "session.zarr"
    first, again = tmp_path / "rig-1.toml", tmp_path / "rig-2.toml"
    connect = f"tcp://127.0.0.1:{_free_base_port()}"
    sim = _start("sim", str(tmp_path / "scene.toml"), "--config-out", str(first), "--speed", "4")
    daemon = sim_again = None
    try:
        _wait(lambda: first.exists() or sim.poll() is not None, "the sim's rig config")
        daemon = _start("daemon", "--config", str(first), "--port", connect.rsplit(":", 1)[1])
        _wait_up(daemon, connect)
        submitted = _cli("submit", str(tmp_path / "plan.toml"), "--archive", str(archive),
                         "--connect", connect)  # fmt: skip
        assert submitted.returncode == 0, submitted.stdout + submitted.stderr
        _wait(lambda: _committed(connect) >= 1, "a committed step")
        sim.send_signal(signal.SIGKILL)
        assert sim.wait(10) == -signal.SIGKILL
        paused = client.wait_for_state(connect, ("paused", *client.TERMINAL_STATES), timeout_s=120)
        assert paused["state"] == "paused", paused["session"]["reason"]
        assert paused["session"]["fault"]["device"]
        assert _cli("abort", "--connect", connect).returncode == 0

        sim_again = _start(
            "sim", str(tmp_path / "scene.toml"), "--config-out", str(again), "--speed", "4"
        )
        _wait(lambda: again.exists() or sim_again.poll() is not None, "the new rig config")
        resumed = _cli("resume", str(archive), "--config", str(again), "--connect", connect)
        assert resumed.returncode == 0, resumed.stdout + resumed.stderr
        final = client.wait_for_state(connect, client.TERMINAL_STATES, settled=True, timeout_s=240)
        assert final["state"] == "done", final["session"]
    finally:
        for proc in (daemon, sim_again, sim):
            if proc is not None:
                _stop(proc)
    with Archive.open(archive) as arch:
        assert arch.committed_steps() == tuple(range(final["session"]["steps"]))
