"""What an attacker on the daemon's sockets tried: a 5,000-digit integer in a request
(idle and mid-session) or in a worker's heartbeat, a NUL byte in an archive path. Each
is an error reply naming the field, or a dropped message; the daemon goes on."""

import json

import pytest
import zmq

from orchestrator.client import DaemonClient, DaemonRequestError, wait_for_state
from orchestrator.wire.protocol import MAX_INT_DIGITS
from tests.orchestrator.daemon.conftest import LAMP_PLAN, running_daemon

BIG = b"9" * 5000


def _raw(endpoints, body: bytes) -> dict:
    with DaemonClient(endpoints, timeout_s=5.0, retries=0) as client:
        return client.request_raw([body])


@pytest.mark.parametrize(
    ("body", "named"),
    [
        (b'{"id":"x","command":"status","args":{"a":' + BIG + b"}}", "of 5000 digits"),
        (b'{"id":"x","command":"status","args":{"a":-' + BIG + b"}}", "of 5000 digits"),
        (b'{"id":' + BIG + b',"command":"status"}', "of 5000 digits"),
        (b'{"id":"x","command":"status","args":{"a":1e999}}', "'1e999', which is not finite"),
        (b'{"id":"x","command":"status","args":{"a":NaN}}', "'NaN', which is not finite"),
    ],
)
def test_a_number_python_cannot_hold_is_a_malformed_reply(config, rig, body, named):
    with running_daemon(config, rig) as endpoints:
        reply = _raw(endpoints, body)
        assert reply["error"]["code"] == "malformed"
        assert named in reply["error"]["message"]
        if "digits" in named:
            assert f"the limit is {MAX_INT_DIGITS}" in reply["error"]["message"]
        assert _raw(endpoints, b'{"id":"s","command":"status"}')["ok"]


def test_a_huge_integer_mid_session_leaves_the_session_running(config, rig, tmp_path):
    rig.real_delay_s = 0.01
    with running_daemon(config, rig) as endpoints, DaemonClient(endpoints) as client:
        client.request("submit", plan_toml=LAMP_PLAN, archive=str(tmp_path / "s.zarr"))
        wait_for_state(endpoints, ("running",))
        reply = _raw(endpoints, b'{"id":"x","command":"status","args":{"a":' + BIG + b"}}")
        assert reply["error"]["code"] == "malformed"
        done = wait_for_state(endpoints, ("done",), settled=True)
    assert done["session"]["committed"] == done["session"]["steps"]


def test_a_worker_heartbeat_with_a_huge_step_is_dropped(config, rig, tmp_path):
    with running_daemon(config, rig) as endpoints:
        ctx = zmq.Context()
        push = ctx.socket(zmq.PUSH)
        push.linger = 1000
        push.connect(endpoints.results)
        header = b'{"kind":"heartbeat","worker":"w","stage":"stats","step":' + BIG + b"}"
        push.send_multipart([header])
        push.send_multipart([b'{"kind":"heartbeat","worker":"w","step":1e999,"stage":"s"}'])
        push.close()
        ctx.term()
        with DaemonClient(endpoints) as client:
            client.request("submit", plan_toml=LAMP_PLAN, archive=str(tmp_path / "s.zarr"))
            done = wait_for_state(endpoints, ("done",), settled=True)
    assert done["session"]["committed"] == done["session"]["steps"]


@pytest.mark.parametrize("where", ["args", "plan"])
def test_a_nul_byte_in_the_archive_path_is_named(config, rig, tmp_path, where):
    path = str(tmp_path / "a\x00b.zarr")
    args = {"archive": path} if where == "args" else {}
    plan = LAMP_PLAN + (f"[output]\narchive = {json.dumps(path)}\n" if where == "plan" else "")
    with running_daemon(config, rig) as endpoints, DaemonClient(endpoints) as client:
        with pytest.raises(DaemonRequestError) as info:
            client.request("submit", plan_toml=plan, **args)
        assert "holds a NUL byte, which no path can hold" in info.value.message
        if where == "args":
            assert (info.value.code, info.value.field) == ("invalid", "args.archive")
        else:
            assert info.value.code == "plan_invalid" and "output.archive" in info.value.message
        with pytest.raises(DaemonRequestError, match="NUL byte") as info:
            client.request("resume", archive=path)
        assert info.value.code == "invalid"
        assert client.request("status")["state"] == "idle"
