"""Processes that die: a worker killed mid-stream loses no frame; a daemon killed with
SIGKILL mid-session resumes from its archive with every step exactly once."""

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from orchestrator.client import DaemonClient, follow, wait_for_state
from orchestrator.wire.endpoints import Endpoints
from rig.archive import Archive
from rig.errors import RigError
from rig.plan import parse_plan
from rig.schedule import compile_plan
from tests.orchestrator.daemon.conftest import LAMP_PLAN, TINY_PLAN, running_daemon
from tests.orchestrator.daemon.test_session import _check_archive

# Sessions, subprocesses or benches: the full tier only (make test), not make quick.
pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[3]


def daemon_json(endpoints: Endpoints) -> str:
    return json.dumps(endpoints.__dict__)


def _spawn(module: str, *args: str) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-m", module, *args],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        text=True,
    )


def _stop(proc: subprocess.Popen) -> None:
    if proc.poll() is None:
        proc.send_signal(signal.SIGTERM)
    proc.wait(10)
    proc.stdout.close()


def test_a_worker_killed_mid_stream_loses_no_frame(config, rig, tmp_path):
    path = tmp_path / "w.zarr"
    settings = {"resend_after_s": 0.3, "worker_timeout_s": 1.0}
    with running_daemon(config, rig, **settings) as endpoints:
        spec = daemon_json(endpoints)
        dying = _spawn("tests.orchestrator.daemon.worker_proc", spec, "dying", "--die-after", "3")
        steady = _spawn("tests.orchestrator.daemon.worker_proc", spec, "steady")
        try:
            with DaemonClient(endpoints) as client:
                deadline = time.monotonic() + 20
                while client.request("status")["workers"] < 2:
                    assert time.monotonic() < deadline, "the workers never said hello"
                    time.sleep(0.05)
                client.request("submit", plan_toml=TINY_PLAN, archive=str(path))
                final = wait_for_state(endpoints, ("done",), settled=True)
            assert dying.wait(10) == -signal.SIGKILL
        finally:
            _stop(dying)
            _stop(steady)
    stream = final["stream"]
    assert stream["resent"] >= 1 and stream["not_streamed"] == 0
    table, _ = _check_archive(path, config, TINY_PLAN)
    with Archive.open(path) as archive:
        stats = archive.material["live/stats"]
        for camera in set(table["camera"]):
            rows = table[table["camera"] == camera]
            got = sorted(zip(stats[camera]["step"][:], stats[camera]["sub"][:], strict=True))
            assert got == sorted(zip(rows["step"], rows["sub"], strict=True))  # each exactly once


def test_daemon_killed_mid_session_resumes_without_loss_or_repeat(config, tmp_path):
    path = tmp_path / "k.zarr"
    daemon = _spawn("tests.orchestrator.daemon.soft_daemon", "--delay", "0.01")
    try:
        endpoints = Endpoints(**json.loads(daemon.stdout.readline()))
        with DaemonClient(endpoints) as client:
            client.request("submit", plan_toml=LAMP_PLAN, archive=str(path))
            for event in follow(endpoints, timeout_s=10):
                if event["topic"] == "progress" and event["step"] >= 4:
                    break
            daemon.send_signal(signal.SIGKILL)
            assert daemon.wait(10) == -signal.SIGKILL
    finally:
        _stop(daemon)
    with Archive.open(path) as archive:
        before = archive.committed_steps()
    steps = len(compile_plan(parse_plan(LAMP_PLAN), config).steps)
    assert 4 <= len(before) < steps
    again = _spawn("tests.orchestrator.daemon.soft_daemon")
    try:
        endpoints = Endpoints(**json.loads(again.stdout.readline()))
        with DaemonClient(endpoints) as client:
            resumed = client.request("resume", archive=str(path))
            assert resumed["session"]["committed"] == len(before)
            done = wait_for_state(endpoints, ("done",), settled=True)
            client.request("shutdown")
        assert again.wait(10) == 0
    finally:
        _stop(again)
    _check_archive(path, config, LAMP_PLAN)  # every step exactly once, frames as made
    with Archive.open(path) as archive:
        starts = [e.payload for e in archive.events("session") if e.payload["action"] == "start"]
        assert [s["committed"] for s in starts] == [0, len(before)]
    assert done["session"]["committed"] == done["session"]["steps"]


def _live_rows_now(path: Path) -> set[tuple[str, int, int]]:
    """:func:`_live_rows` of an archive being written: empty while a batch is half written."""
    try:
        return _live_rows(path)
    except (AssertionError, OSError, KeyError, ValueError, RigError):
        return set()


def _live_rows(path: Path) -> set[tuple[str, int, int]]:
    """(camera, step, sub) of every complete row of live/stats; the arrays agree in length."""
    rows = set()
    with Archive.open(path) as archive:
        if "live" not in archive.material:
            return rows
        stats = archive.material["live/stats"]
        for camera in stats.group_keys():
            group = stats[camera]
            n = group["step"].shape[0]
            assert group["sub"].shape[0] == group["mean"].shape[0] == n
            pairs = zip(group["step"][:], group["sub"][:], strict=True)
            found = [(camera, int(step), int(sub)) for step, sub in pairs]
            assert len(set(found)) == len(found)  # each frame at most once
            rows |= set(found)
    return rows


def test_live_results_written_before_a_crash_survive_it(config, tmp_path):
    path = tmp_path / "live.zarr"
    # a step's cameras read together: 0.5 s of real time a step, killed mid-session
    daemon = _spawn("tests.orchestrator.daemon.soft_daemon", "--delay", "0.5")
    worker = None
    try:
        endpoints = Endpoints(**json.loads(daemon.stdout.readline()))
        worker = _spawn("tests.orchestrator.daemon.worker_proc", daemon_json(endpoints), "w")
        with DaemonClient(endpoints) as client:
            deadline = time.monotonic() + 20
            while client.request("status")["workers"] < 1:
                assert time.monotonic() < deadline, "the worker never said hello"
                time.sleep(0.05)
            client.request("submit", plan_toml=LAMP_PLAN, archive=str(path))
            for event in follow(endpoints, timeout_s=10):
                if event["topic"] == "progress" and event["step"] >= 4:
                    break
            # killed once a flush has put rows on disk (the writer flushes every second; a
            # loaded machine's worker may send its first results later than that)
            deadline = time.monotonic() + 30
            while not _live_rows_now(path):
                assert time.monotonic() < deadline, "no live row was written within 30 s"
                time.sleep(0.1)
            daemon.send_signal(signal.SIGKILL)
            assert daemon.wait(10) == -signal.SIGKILL
    finally:
        _stop(daemon)
        if worker is not None:
            _stop(worker)
    with Archive.open(path) as archive:
        committed = set(archive.committed_steps())
    before = _live_rows(path)
    assert before and {step for _, step, _ in before} <= committed  # kept, and only real ones
    again = _spawn("tests.orchestrator.daemon.soft_daemon")
    worker = None
    try:
        endpoints = Endpoints(**json.loads(again.stdout.readline()))
        worker = _spawn("tests.orchestrator.daemon.worker_proc", daemon_json(endpoints), "w2")
        with DaemonClient(endpoints) as client:
            deadline = time.monotonic() + 20
            while client.request("status")["workers"] < 1:
                assert time.monotonic() < deadline, "the worker never said hello"
                time.sleep(0.05)
            client.request("resume", archive=str(path))
            wait_for_state(endpoints, ("done",), settled=True)
            client.request("shutdown")
        assert again.wait(10) == 0
    finally:
        _stop(again)
        if worker is not None:
            _stop(worker)
    table, _ = _check_archive(path, config, LAMP_PLAN)
    after = _live_rows(path)
    resumed = {(str(c), int(s), int(u)) for c, s, u in zip(
        table["camera"], table["step"], table["sub"], strict=True) if s not in committed}
    assert before <= after and resumed <= after  # the old rows stay, the new steps all come
