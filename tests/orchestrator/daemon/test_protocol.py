"""Bad input on every socket: each gets an error naming the problem, and the daemon goes on."""

import json
import random

import numpy as np
import pytest
import zmq

from orchestrator.client import DaemonClient, DaemonRequestError, wait_for_state
from orchestrator.wire.endpoints import DaemonSettings, Endpoints
from orchestrator.wire.protocol import (
    MAX_CONTROL_BYTES,
    ArraySpec,
    FrameHeader,
    MessageError,
    decode_frame,
    decode_result,
    encode_frame,
    parse_request,
)
from rig.errors import ConfigError
from tests.orchestrator.daemon.conftest import LAMP_PLAN, running_daemon

GOOD = {"id": "r1", "command": "status", "args": {}}


def _body(**changes):
    data = {**GOOD, **changes}
    return json.dumps({k: v for k, v in data.items() if v is not ...}).encode()


@pytest.mark.parametrize(
    ("body", "code", "field"),
    [
        (b"\xff\xfe", "malformed", None),
        (b"{not json", "malformed", None),
        (b"[1, 2]", "malformed", None),
        (_body(id=...), "invalid", "id"),
        (_body(id=""), "invalid", "id"),
        (_body(id=7), "invalid", "id"),
        (_body(command=...), "invalid", "command"),
        (_body(extra=1), "invalid", "extra"),
        (_body(command="launch"), "unknown_command", "command"),
        (_body(args={"x": 1}), "invalid", "args.x"),
        (_body(command="submit", args={}), "invalid", "args.plan_toml"),
        (_body(command="submit", args={"plan_toml": 5}), "invalid", "args.plan_toml"),
        (_body(command="calibrate", args={"target": "moon"}), "invalid", "args.target"),
        (b"{" + b" " * MAX_CONTROL_BYTES + b"}", "too_large", None),
    ],
)
def test_parse_request_names_the_problem(body, code, field):
    with pytest.raises(MessageError) as info:
        parse_request(body)
    assert info.value.code == code
    assert info.value.field == field
    if field is not None:
        assert repr(field) in info.value.message or field in info.value.message


def test_frame_roundtrip_and_size_checks():
    image = np.arange(4 * 5 * 3, dtype=np.uint16).reshape(4, 5, 3)
    header = FrameHeader(
        frame_id=3, session="s", step=1, kind="btf", camera="cam0", sub=0,
        exposure_s=0.02, timestamp=1.0, array=ArraySpec(dtype="uint16", shape=(4, 5, 3)),
    )  # fmt: skip
    parts = [bytes(p) for p in encode_frame(header, image)]
    got_header, got = decode_frame(parts)
    assert got_header == header
    np.testing.assert_array_equal(got, image)
    with pytest.raises(MessageError, match=r"buffer has 118 bytes.*needs 120"):
        decode_frame([parts[0], parts[1][:-2]])
    with pytest.raises(MessageError, match="2 parts"):
        decode_frame(parts[:1])
    bad = json.loads(parts[0])
    bad["array"]["dtype"] = "object"
    with pytest.raises(MessageError) as info:
        decode_frame([json.dumps(bad).encode(), parts[1]])
    assert info.value.field == "array.dtype"
    with pytest.raises(MessageError, match="lists 1 arrays but 0 buffers"):
        decode_result(
            [json.dumps({"kind": "result", "worker": "w", "stage": "s", "frame_id": 1,
                         "arrays": [{"name": "m", "dtype": "float32", "shape": [3]}]}).encode()]
        )  # fmt: skip


def _raw(endpoints, parts):
    with DaemonClient(endpoints, timeout_s=2.0, retries=0) as client:
        return client.request_raw(parts)


def test_bad_requests_get_error_replies_and_the_daemon_goes_on(config, rig, tmp_path):
    with running_daemon(config, rig) as endpoints:
        reply = _raw(endpoints, [b"{oops"])
        assert reply == {"id": None, "ok": False, "error": reply["error"]}
        assert reply["error"]["code"] == "malformed"
        reply = _raw(endpoints, [_body(), b"second part"])
        assert (
            reply["error"]["code"] == "malformed" and "one body part" in reply["error"]["message"]
        )
        reply = _raw(endpoints, [b"x" * (MAX_CONTROL_BYTES + 1)])
        assert reply["error"]["code"] == "too_large"
        reply = _raw(endpoints, [_body(id="q9", command="fly")])
        assert reply["id"] == "q9" and reply["error"]["code"] == "unknown_command"
        assert "submit" in reply["error"]["message"]  # lists the valid commands
        with DaemonClient(endpoints) as client:
            bad_plan = "[sample]\nname = 'bad name!'\n[captures]\n"
            with pytest.raises(DaemonRequestError) as info:
                client.request("submit", plan_toml=bad_plan, archive=str(tmp_path / "b.zarr"))
            assert info.value.code == "plan_invalid" and "sample.name" in info.value.message
            with pytest.raises(DaemonRequestError) as info:
                client.request("pause")
            assert info.value.code == "illegal_state"
            assert "while the session is idle" in info.value.message
            with pytest.raises(DaemonRequestError, match="not_built"):
                client.request("calibrate", target="cameras")
            rig.real_delay_s = 0.01
            client.request("submit", plan_toml=LAMP_PLAN, archive=str(tmp_path / "a.zarr"))
            with pytest.raises(DaemonRequestError) as info:
                client.request("submit", plan_toml=LAMP_PLAN, archive=str(tmp_path / "c.zarr"))
            assert info.value.code == "busy"
            rig.real_delay_s = 0.0
            wait_for_state(endpoints, ("done",), settled=True)
            with pytest.raises(DaemonRequestError) as info:  # the archive exists
                client.request("submit", plan_toml=LAMP_PLAN, archive=str(tmp_path / "a.zarr"))
            assert info.value.code == "rejected" and "already exists" in info.value.message
            assert client.request("status")["state"] == "done"


def test_a_retried_request_is_answered_once(config, rig, tmp_path):
    with running_daemon(config, rig) as endpoints:
        args = {"plan_toml": LAMP_PLAN, "archive": str(tmp_path / "r.zarr")}
        body = json.dumps({"id": "same", "command": "submit", "args": args})
        first = _raw(endpoints, [body.encode()])
        again = _raw(endpoints, [body.encode()])
        assert first == again and first["ok"]
        wait_for_state(endpoints, ("done",), settled=True)


def _garbage(rng: random.Random) -> list[bytes]:
    kind = rng.randrange(8)
    if kind == 0:
        return [rng.randbytes(rng.randrange(0, 200))]
    if kind == 1:
        return [_body(command=rng.choice(["", "x" * 70, "SUBMIT", "status "]))]
    if kind == 2:
        return [_body(args={"archive": rng.random()}, command="resume")]
    if kind == 3:
        return [_body(), rng.randbytes(10)]
    if kind == 4:
        return [json.dumps(rng.choice([None, 1, "s", [], {"id": None}])).encode()]
    if kind == 5:
        return [_body(command="submit", args={"plan_toml": "x = ", "source": "t"})]
    if kind == 6:
        return [_body(id="i" * 200)]
    return [_body(command="abort", args={"now": True})]


def test_a_thousand_malformed_messages_then_a_normal_session(config, rig, tmp_path):
    rng = random.Random(5)
    with running_daemon(config, rig) as endpoints:
        ctx = zmq.Context()
        dealer = ctx.socket(zmq.DEALER)
        dealer.linger = 0
        try:
            dealer.connect(endpoints.control)
            sent = [_garbage(rng) for _ in range(1000)]
            for parts in sent:
                dealer.send_multipart([b"", *parts])
            codes = []
            for _ in sent:
                assert dealer.poll(5000), "the daemon stopped answering"
                envelope, body = dealer.recv_multipart()
                assert envelope == b""
                reply = json.loads(body)
                assert reply["ok"] is False
                codes.append(reply["error"]["code"])
        finally:
            dealer.close(linger=0)
            ctx.term()
        assert set(codes) <= {"malformed", "invalid", "unknown_command", "plan_invalid"}
        assert len(set(codes)) >= 3
        with DaemonClient(endpoints) as client:
            client.request("submit", plan_toml=LAMP_PLAN, archive=str(tmp_path / "ok.zarr"))
            done = wait_for_state(endpoints, ("done",), settled=True)
    assert done["session"]["committed"] == done["session"]["steps"]


def test_beyond_loopback_needs_curve_keys(tmp_path):
    with pytest.raises(ConfigError, match="needs CURVE"):
        DaemonSettings(host="0.0.0.0").check_exposure()
    with pytest.raises(ConfigError, match="no such file"):
        DaemonSettings(
            host="10.1.2.3", curve_secret_key=tmp_path / "k", curve_clients_dir=tmp_path / "c"
        ).check_exposure()
    for host in ("127.0.0.1", "localhost", "::1", "127.3.4.5"):
        DaemonSettings(host=host).check_exposure()


def test_endpoints_from_an_address():
    e = Endpoints.from_base("tcp://localhost:6000")
    assert (e.control, e.results) == ("tcp://localhost:6000", "tcp://localhost:6003")
    assert Endpoints.from_base("tcp://127.0.0.2").frames == "tcp://127.0.0.2:5572"
    for bad in ("udp://x:1", "tcp://:5", "tcp://h:notaport", "tcp://h:65535"):
        with pytest.raises(ConfigError, match="daemon address"):
            Endpoints.from_base(bad)
