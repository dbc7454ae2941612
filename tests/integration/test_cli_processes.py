"""The user's multi-process setup, on the command line: `rig sim serve` in one process,
`rig daemon` in another, `rig submit` / `rig status` / `rig resume` as clients. The daemon
is killed with SIGKILL mid-session; a new one resumes the archive with every step once —
on the Wang rig and on the Bonn lab (`rig sim --config-kind bonn`)."""

from __future__ import annotations

import contextlib
import random
import select
import signal
import socket
import subprocess
import sys
import time
import tomllib
from pathlib import Path

import pytest
import tomli_w

from orchestrator import client
from rig.archive import Archive

# Sessions, subprocesses or benches: the full tier only (make test), not make quick.
pytestmark = pytest.mark.slow

RIG = str(Path(sys.executable).with_name("rig"))
ROOT = Path(__file__).resolve().parents[2]
PLAN = """
[sample]
name = "cli"
[captures.ps]
lights = {theta_deg = 45, count = 6}
[captures.btf]
views = [[0, 0]]
lights = [[30, 0], [30, 120], [30, 240]]
"""


def _free_base_port() -> int:
    """A port P with P … P + 3 free on loopback (the daemon's four sockets), below the
    kernel's ephemeral range, so that neither the simulated rig's peers (bound to port 0)
    nor a client's outgoing connection can take one of them after the probe."""
    low = int(Path("/proc/sys/net/ipv4/ip_local_port_range").read_text().split()[0])
    for base in random.sample(range(max(1024, low - 12000), low - 4, 4), 200):
        with contextlib.ExitStack() as stack:
            try:
                for port in range(base, base + 4):
                    s = stack.enter_context(socket.socket())
                    s.bind(("127.0.0.1", port))
            except OSError:
                continue
        return base
    raise RuntimeError("no four consecutive free ports on loopback")


def _start(*args: str) -> subprocess.Popen:
    return subprocess.Popen(
        [RIG, *args], cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True
    )


def _stop(proc: subprocess.Popen) -> str:
    if proc.poll() is None:
        proc.send_signal(signal.SIGTERM)
    try:
        out, _ = proc.communicate(timeout=20)
    except subprocess.TimeoutExpired:
        proc.kill()
        out, _ = proc.communicate()
    return out


def _cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([RIG, *args], cwd=ROOT, capture_output=True, text=True, timeout=120)


def _wait_up(daemon: subprocess.Popen, connect: str, what: str = "the daemon") -> None:
    """Until ``rig status`` reaches the daemon; a daemon that exits fails at once with
    what it printed."""
    _wait(lambda: daemon.poll() is not None or _cli("status", "--connect", connect).returncode == 0,
          what)  # fmt: skip
    assert daemon.poll() is None, f"{what} exited: {_stop(daemon)}"


def _wait(predicate, what: str, timeout_s: float = 60.0):
    deadline = time.monotonic() + timeout_s
    while True:
        value = predicate()
        if value:
            return value
        assert time.monotonic() < deadline, f"timed out waiting for {what}"
        time.sleep(0.1)


@pytest.mark.parametrize("kind", ["wang", "bonn"])
def test_sim_serve_daemon_submit_kill_resume(tmp_path, kind):
    scene = tomllib.loads((ROOT / "examples/scenes/bumps.toml").read_text())
    scene["render"]["scale"] = 0.2
    (tmp_path / "scene.toml").write_text(tomli_w.dumps(scene))
    (tmp_path / "plan.toml").write_text(PLAN)
    config, archive = tmp_path / "sim-rig.toml", tmp_path / "session.zarr"
    connect = f"tcp://127.0.0.1:{_free_base_port()}"
    port = connect.rsplit(":", 1)[1]
    sim = _start("sim", str(tmp_path / "scene.toml"), "--config-out", str(config), "--speed", "4",
                 "--config-kind", kind)  # fmt: skip
    daemon = again = None
    try:
        _wait(lambda: config.exists() or sim.poll() is not None, "the sim's rig config")
        assert sim.poll() is None, _stop(sim)
        daemon = _start("daemon", "--config", str(config), "--port", port)
        _wait_up(daemon, connect)
        submitted = _cli("submit", str(tmp_path / "plan.toml"), "--archive", str(archive),
                         "--connect", connect)  # fmt: skip
        assert submitted.returncode == 0, submitted.stdout + submitted.stderr
        _wait(
            lambda: (client.status(connect=connect)["session"] or {}).get("committed", 0) >= 2,
            "two committed steps",
        )
        daemon.send_signal(signal.SIGKILL)
        assert daemon.wait(10) == -signal.SIGKILL
        with Archive.open(archive) as arch:
            before = arch.committed_steps()
        again = _start("daemon", "--config", str(config), "--port", port)
        _wait_up(again, connect, "the new daemon")
        resumed = _cli("resume", str(archive), "--connect", connect)
        assert resumed.returncode == 0, resumed.stdout + resumed.stderr
        followed = _cli("status", "--follow", "--connect", connect)
        assert followed.returncode == 0, followed.stdout + followed.stderr
        final = client.wait_for_state(connect, client.TERMINAL_STATES, settled=True)
        assert final["state"] == "done", final
        assert _cli("shutdown", "--connect", connect).returncode == 0
        assert again.wait(20) == 0
    finally:
        for proc in (again, daemon, sim):
            if proc is not None:
                _stop(proc)
    with Archive.open(archive) as arch:
        committed = arch.committed_steps()
        table = arch.frame_table()
        starts = [e.payload for e in arch.events("session") if e.payload["action"] == "start"]
    assert 2 <= len(before) < len(committed)
    assert committed == tuple(range(final["session"]["steps"]))
    keys = [(int(r["step"]), str(r["camera"]), int(r["sub"])) for r in table]
    assert len(keys) == len(set(keys)) == final["session"]["frames"]  # nothing captured twice
    assert [s["committed"] for s in starts] == [0, len(before)]


def _line(proc: subprocess.Popen, timeout_s: float = 60.0) -> str:
    """The next line ``proc`` prints; fails when none comes in ``timeout_s``."""
    ready, _, _ = select.select([proc.stdout], [], [], timeout_s)
    assert ready, f"no line from {proc.args} in {timeout_s} s"
    return proc.stdout.readline()


def test_status_follow_ends_unreachable_when_the_daemon_is_killed():
    connect = f"tcp://127.0.0.1:{_free_base_port()}"
    daemon = _start("daemon", "--port", connect.rsplit(":", 1)[1])
    follower = None
    try:
        _wait_up(daemon, connect)
        follower = _start("status", "--follow", "--connect", connect)
        assert _line(follower).strip() == "daemon: idle"  # piped: printed as it comes
        daemon.send_signal(signal.SIGKILL)
        daemon.wait(10)
        out, _ = follower.communicate(timeout=120)  # it used to wait until killed
        assert follower.returncode == 1, out
        assert "the daemon is unreachable" in " ".join(out.split())
        assert "Traceback" not in out
    finally:
        for proc in (follower, daemon):
            if proc is not None:
                _stop(proc)


def test_status_follow_prints_line_by_line_and_returns_on_a_pause(tmp_path):
    scene = tomllib.loads((ROOT / "examples/scenes/bumps.toml").read_text())
    scene["render"]["scale"] = 0.2
    (tmp_path / "scene.toml").write_text(tomli_w.dumps(scene))
    (tmp_path / "plan.toml").write_text(PLAN)
    config = tmp_path / "sim-rig.toml"
    connect = f"tcp://127.0.0.1:{_free_base_port()}"
    sim = _start("sim", str(tmp_path / "scene.toml"), "--config-out", str(config), "--speed", "1")
    daemon = follower = None
    try:
        _wait(lambda: config.exists() or sim.poll() is not None, "the sim's rig config")
        daemon = _start("daemon", "--config", str(config), "--port", connect.rsplit(":", 1)[1])
        _wait_up(daemon, connect)
        follower = _start("status", "--follow", "--connect", connect)
        assert _line(follower).strip() == "daemon: idle"
        submitted = _cli("submit", str(tmp_path / "plan.toml"), "--archive",
                         str(tmp_path / "s.zarr"), "--connect", connect)  # fmt: skip
        assert submitted.returncode == 0, submitted.stdout + submitted.stderr
        while "→ running" not in (line := _line(follower)):
            assert line, "the follower ended before the session ran"
        assert follower.poll() is None  # the line came while the session runs
        assert _cli("pause", "--connect", connect).returncode == 0
        out, _ = follower.communicate(timeout=60)  # it used to follow until the session ended
        assert follower.returncode == 3, out
        assert "→ paused" in out and "daemon: paused" in out
        assert _cli("abort", "--connect", connect).returncode == 0
    finally:
        for proc in (follower, daemon, sim):
            if proc is not None:
                _stop(proc)
