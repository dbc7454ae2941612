"""How sessions end and come back: abort is prompt even with frames stuck at a worker,
a finished archive is not resumed, and a resume takes the connections of the rig config
it is given while refusing a different geometry."""

import threading
import time

import pytest
import tomli_w
import zmq

from orchestrator import client
from orchestrator.cli.session_cmd import FaultHints
from orchestrator.client import DaemonClient, DaemonRequestError, wait_for_state
from orchestrator.local import run_local
from orchestrator.wire.protocol import ResultHeader, encode_result
from rig.archive import Archive
from tests.orchestrator.daemon.conftest import LAMP_PLAN, running_daemon
from tests.orchestrator.daemon.soft import soft_devices
from tests.orchestrator.daemon.test_session import _check_archive


class _StuckWorker:
    """Says hello and keeps beating, takes frames and never answers one."""

    def __init__(self, endpoints):
        self._ctx = zmq.Context()
        self._frames = self._ctx.socket(zmq.PULL)
        self._results = self._ctx.socket(zmq.PUSH)
        for sock, url in ((self._frames, endpoints.frames), (self._results, endpoints.results)):
            sock.linger = 0
            sock.connect(url)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._beat, name="stuck-worker")

    def _beat(self):
        kind = "hello"
        while not self._stop.is_set():
            header = ResultHeader(kind=kind, worker="stuck", stage="stats")
            self._results.send_multipart(encode_result(header))
            kind = "heartbeat"
            self._stop.wait(0.05)

    def __enter__(self):
        self._thread.start()
        return self

    def __exit__(self, *exc):
        self._stop.set()
        self._thread.join()
        self._frames.close(linger=0)
        self._results.close(linger=0)
        self._ctx.term()


def test_abort_is_prompt_while_frames_wait_at_a_stuck_worker(config, rig, tmp_path):
    options = {"max_in_flight": 2, "resend_after_s": 60.0, "worker_timeout_s": 1.0}
    with running_daemon(config, rig, **options) as endpoints:
        with _StuckWorker(endpoints), DaemonClient(endpoints) as control:
            while control.request("status")["workers"] < 1:
                time.sleep(0.01)
            control.request("submit", plan_toml=LAMP_PLAN, archive=str(tmp_path / "a.zarr"))
            # the session thread waits to hand over frames nobody takes
            while control.request("status")["stream"]["in_flight"] < 2:
                time.sleep(0.01)
            time.sleep(0.2)
            # settled within 10 s, though a frame would be resent only after 60 s: the
            # abort does not wait for the stuck worker (no wall-clock bound of its own)
            aborted = client.abort(connect=endpoints, timeout_s=10)
            assert aborted["state"] == "aborted" and not aborted["busy"]
            assert aborted["stream"]["in_flight"] == 0
        # a submit right after is taken (the stuck worker is gone: frames stay in the archive)
        with DaemonClient(endpoints) as control:
            control.request("submit", plan_toml=LAMP_PLAN, archive=str(tmp_path / "b.zarr"))
            done = wait_for_state(endpoints, ("done",), settled=True, timeout_s=60)
    with Archive.open(tmp_path / "a.zarr") as archive:
        committed = archive.committed_steps()
    assert committed == tuple(range(len(committed)))  # committed frames stay
    assert aborted["session"]["committed"] == len(committed)
    assert done["session"]["committed"] == done["session"]["steps"]


def _abort_midway(endpoints, rig, path):
    rig.real_delay_s = 0.01
    with DaemonClient(endpoints) as control:
        control.request("submit", plan_toml=LAMP_PLAN, archive=str(path))
        while (control.request("status")["session"] or {}).get("committed", 0) < 2:
            time.sleep(0.01)
    status = client.abort(connect=endpoints)
    rig.real_delay_s = 0.0
    return status


def test_resume_takes_new_connections_and_refuses_a_new_geometry(config, rig, tmp_path):
    path = tmp_path / "s.zarr"
    lamp_bank = config.lamp_bank.device.model_copy(update={"host": "10.0.0.7", "port": 1502})
    moved = config.model_copy(
        update={"lamp_bank": config.lamp_bank.model_copy(update={"device": lamp_bank})}
    )
    wider = moved.model_copy(
        update={"camera_arc": moved.camera_arc.model_copy(update={"radius_mm": 812.5})}
    )
    with running_daemon(config, rig) as endpoints, DaemonClient(endpoints) as control:
        aborted = _abort_midway(endpoints, rig, path)
        with pytest.raises(DaemonRequestError) as info:
            control.request(
                "resume", archive=str(path),
                config_toml=tomli_w.dumps(wider.model_dump(mode="json", exclude_none=True)),
                config_source="wider.toml",
            )  # fmt: skip
        assert info.value.code == "rejected"
        assert "differs from the recorded one in camera_arc.radius_mm" in info.value.message
        assert f"recorded {config.camera_arc.radius_mm!r}, now 812.5" in info.value.message
        control.request(
            "resume", archive=str(path),
            config_toml=tomli_w.dumps(moved.model_dump(mode="json", exclude_none=True)),
            config_source="moved.toml",
        )  # fmt: skip
        done = wait_for_state(endpoints, ("done",), settled=True, timeout_s=60)
        assert done["session"]["committed"] == done["session"]["steps"]
        assert aborted["session"]["committed"] < done["session"]["steps"]
        with pytest.raises(DaemonRequestError) as info:
            control.request("resume", archive=str(path))
        assert info.value.field == "args.archive"
        assert "its session finished (" in info.value.message
        assert "nothing to resume" in info.value.message
    _check_archive(path, config, LAMP_PLAN)


def test_a_daemon_on_another_rig_refuses_the_resume(config, rig, tmp_path):
    path = tmp_path / "s.zarr"
    with running_daemon(config, rig) as endpoints:
        _abort_midway(endpoints, rig, path)
    other = config.model_copy(
        update={"turntable": config.turntable.model_copy(
            update={"axis": config.turntable.axis.model_copy(update={"speed_deg_s": 7.0})})}
    )  # fmt: skip
    with running_daemon(other, rig) as endpoints, DaemonClient(endpoints) as control:
        with pytest.raises(DaemonRequestError) as info:
            control.request("resume", archive=str(path))
        assert "turntable.axis.speed_deg_s" in info.value.message
        assert control.request("status")["state"] == "idle"


def test_rig_run_says_what_happened_and_what_to_do_after_a_fault(config, rig, tmp_path, capsys):
    rig.faults.arm("lamps.switch", "dark")
    (tmp_path / "plan.toml").write_text(LAMP_PLAN)
    resumers = []

    def resume_when_paused(event):  # the user, in another terminal, after reading the hint
        # A fault before the client subscribed shows only in the statuses of the pause.
        paused = event.get("to") == "paused" or event.get("state") == "paused"
        if event.get("topic") in ("state", "status") and paused and not resumers:
            resumer = threading.Thread(target=client.resume, kwargs={"connect": hints.connect})
            resumer.start()
            resumers.append(resumer)

    hints = FaultHints(resume_when_paused)
    final = run_local(
        tmp_path / "plan.toml", config, archive=tmp_path / "a.zarr", on_event=hints,
        devices=soft_devices(rig), clock=rig.clock,
    )  # fmt: skip
    for resumer in resumers:
        resumer.join()
    said = " ".join(capsys.readouterr().out.split())
    assert final["state"] == "done" and len(resumers) == 1
    assert hints.connect.startswith("tcp://127.0.0.1:")
    assert "paused: lamp bank failed at step 0 (switch: lamp ['" in said
    assert f"`rig resume --connect {hints.connect}` to retry that step" in said
    assert f"`rig abort --connect {hints.connect}` to end the session" in said
