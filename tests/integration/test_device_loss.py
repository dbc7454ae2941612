"""Every device vanishes mid-session, as when the simulated rig's process is killed: the
session pauses naming a device (it does not fail), and once the rig is back on other
ports, `resume ARCHIVE --config NEW-RIG` finishes it with every step once."""

from __future__ import annotations

import time

from orchestrator import client
from orchestrator.daemon import DaemonSettings, daemon_thread
from orchestrator.daemon.local import worker_threads
from rig.archive import Archive
from rig.clock import VirtualClock
from rig.config import write_rig_config
from sim.rig import SimulatedRig
from tests.integration.conftest import PLAN


def _committed(endpoints) -> int:
    return (client.status(connect=endpoints)["session"] or {}).get("committed", 0)


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
