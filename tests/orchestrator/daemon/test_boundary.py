"""The request boundary: whatever a request makes go wrong becomes an error reply naming
it, limits hold per message, and the daemon goes on to run a normal session."""

import json
import os
import time

import pytest
import zmq
from hypothesis import HealthCheck, example, given
from hypothesis import strategies as st

from orchestrator.client import (
    DaemonClient,
    DaemonRequestError,
    DaemonUnreachable,
    wait_for_state,
)
from orchestrator.client import abort as client_abort
from orchestrator.daemon import Session
from orchestrator.wire.protocol import MAX_CONTROL_BYTES, MAX_JSON_DEPTH, MAX_PLAN_PAIRS
from rig.archive import Archive
from tests.budgets import fuzz
from tests.orchestrator.daemon.conftest import LAMP_PLAN, running_daemon


def _raw(endpoints, parts):
    with DaemonClient(endpoints, timeout_s=5.0, retries=0) as client:
        return client.request_raw(parts)


def _request(command, **args):
    return json.dumps({"id": "b1", "command": command, "args": args}).encode()


def _finishes_a_session(endpoints, path):
    with DaemonClient(endpoints) as client:
        client.request("submit", plan_toml=LAMP_PLAN, archive=str(path))
        done = wait_for_state(endpoints, ("done",), settled=True)
    assert done["session"]["committed"] == done["session"]["steps"]


def test_deep_nesting_is_refused_naming_the_limit(config, rig, tmp_path):
    with running_daemon(config, rig) as endpoints:
        reply = _raw(endpoints, [b"[" * 100_000])
        assert reply["error"]["code"] == "too_deep"
        assert str(MAX_JSON_DEPTH) in reply["error"]["message"]
        nested = b'{"id": "n", "command": "status", "args": {"a": ' + b"[" * 2000 + b"]" * 2000
        reply = _raw(endpoints, [nested + b"}}"])
        assert reply["error"]["code"] == "too_deep"
        just_over = {"id": "n", "command": "status", "args": {"a": []}}
        inner = just_over["args"]["a"]
        for _ in range(MAX_JSON_DEPTH):
            inner.append([])
            inner = inner[0]
        reply = _raw(endpoints, [json.dumps(just_over).encode()])
        assert reply["error"]["code"] == "too_deep"
        assert _raw(endpoints, [_request("status")])["ok"]
        _finishes_a_session(endpoints, tmp_path / "after.zarr")


def test_the_size_limit_counts_every_part_of_a_message(config, rig):
    part = b"x" * (MAX_CONTROL_BYTES // 2)
    with running_daemon(config, rig) as endpoints:
        reply = _raw(endpoints, [part, part, part])
        assert reply["error"]["code"] == "too_large"
        assert f"the limit is {MAX_CONTROL_BYTES} bytes per message" in reply["error"]["message"]
        assert f"{3 * len(part)} bytes in 3 part(s)" in reply["error"]["message"]
        assert _raw(endpoints, [_request("status")])["ok"]


def test_a_part_far_over_the_limit_is_dropped_unread_and_the_client_says_so(config, rig):
    with running_daemon(config, rig) as endpoints:
        # ZeroMQ drops it before it is whole: no memory held, no reply
        with (
            DaemonClient(endpoints, timeout_s=0.5, retries=0) as client,
            pytest.raises(DaemonUnreachable),
        ):
            client.request_raw([b"x" * (MAX_CONTROL_BYTES + 100_000)] * 3)
        with DaemonClient(endpoints) as client:
            with pytest.raises(DaemonRequestError) as info:  # refused here, never sent
                client.request("submit", plan_toml="#" * (MAX_CONTROL_BYTES + 1))
            assert info.value.code == "too_large"
            assert f"at most {MAX_CONTROL_BYTES} bytes per message" in info.value.message
            assert client.request("status")["state"] == "idle"


def test_an_archive_under_a_file_is_refused_naming_it(config, rig, tmp_path):
    (tmp_path / "afile").write_text("not a folder")
    target = tmp_path / "afile" / "x.zarr"
    with running_daemon(config, rig) as endpoints, DaemonClient(endpoints) as client:
        with pytest.raises(DaemonRequestError) as info:
            client.request("submit", plan_toml=LAMP_PLAN, archive=str(target))
        assert info.value.code == "rejected" and info.value.field == "args.archive"
        assert f"{tmp_path / 'afile'} is a file, not a folder" in info.value.message
        assert client.request("status")["state"] == "idle"
        _finishes_a_session(endpoints, tmp_path / "ok.zarr")


def test_an_unknown_placeholder_in_the_plans_archive_is_a_plan_error(config, rig, tmp_path):
    plan = LAMP_PLAN + '[output]\narchive = "out/{x}.zarr"\n'
    with running_daemon(config, rig) as endpoints, DaemonClient(endpoints) as client:
        with pytest.raises(DaemonRequestError) as info:
            client.request("submit", plan_toml=plan)
        assert info.value.code == "plan_invalid"
        assert "output.archive: unknown placeholder {x}" in info.value.message
        _finishes_a_session(endpoints, tmp_path / "after.zarr")


def test_a_plan_beyond_the_pair_limit_is_refused_before_compiling(config, rig, tmp_path):
    n = MAX_PLAN_PAIRS // 81 + 1
    lights = [[5 + 80 * i / n, (i * 137.5) % 360] for i in range(n)]
    plan = f'[sample]\nname = "big"\n[captures.btf]\nviews = "H1"\nlights = {lights}\n'
    with running_daemon(config, rig) as endpoints, DaemonClient(endpoints) as client:
        with pytest.raises(DaemonRequestError) as info:
            client.request("submit", plan_toml=plan, archive=str(tmp_path / "big.zarr"))
        assert info.value.code == "plan_invalid"
        assert f"{81 * n} (view, light) pairs; the limit is {MAX_PLAN_PAIRS}" in info.value.message
    assert not (tmp_path / "big.zarr").exists()


def test_a_plan_that_fails_to_compile_leaves_nothing_and_the_fixed_plan_runs(config, rig, tmp_path):
    too_long = 2.0 / config.laser.frame_rate_hz
    bad = (
        '[sample]\nname = "scan"\n[captures.mdf]\nviews = [[0, 0]]\n'
        "laser_locations = [[45, 0]]\nscan_step_deg = 5.0\n"
        f"[exposure]\nlaser_exposure_s = {too_long}\n"
    )
    target = tmp_path / "scan.zarr"
    with running_daemon(config, rig) as endpoints, DaemonClient(endpoints) as client:
        with pytest.raises(DaemonRequestError) as info:
            client.request("submit", plan_toml=bad, archive=str(target))
        assert info.value.code == "plan_invalid" and "laser_exposure_s" in info.value.message
        assert not target.exists()
        fixed = bad.replace(f"laser_exposure_s = {too_long}", "laser_exposure_s = 0.001")
        client.request("submit", plan_toml=fixed, archive=str(target))
        assert wait_for_state(endpoints, ("done",), settled=True)["session"]["committed"] == 1


@pytest.mark.parametrize(
    ("raised", "code"),
    [
        (MemoryError(), "too_large"),
        (RecursionError("maximum recursion depth exceeded"), "too_deep"),
        (NotADirectoryError(20, "Not a directory", "/s/afile/x.zarr"), "rejected"),
        (KeyError("x"), "internal"),
    ],
)
def test_any_exception_becomes_an_error_reply_naming_the_request(
    config, rig, tmp_path, monkeypatch, raised, code
):
    def start_new(*args, **kwargs):
        raise raised

    with running_daemon(config, rig) as endpoints:
        with monkeypatch.context() as patch:
            patch.setattr(Session, "start_new", start_new)
            reply = _raw(endpoints, [_request("submit", plan_toml=LAMP_PLAN)])
        assert reply["id"] == "b1" and reply["error"]["code"] == code
        assert "'submit' request" in reply["error"]["message"]
        _finishes_a_session(endpoints, tmp_path / "after.zarr")


_json = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats(allow_nan=False) | st.text(max_size=20),
    lambda inner: (
        st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=8), inner, max_size=4)
    ),
    max_leaves=20,
)
_commands = st.sampled_from(["submit", "status", "pause", "resume", "abort", "calibrate", "", "x"])
_args = st.dictionaries(
    st.sampled_from(["plan_toml", "archive", "source", "target", "x"]),
    st.text(max_size=40) | _json,
    max_size=3,
)
_envelope = st.fixed_dictionaries(
    {"id": st.text(max_size=10) | _json, "command": _commands | _json, "args": _args | _json}
).map(lambda d: json.dumps(d).encode())
#: Numbers Python cannot hold or JSON should not: integers of 41 to 6,000 digits (over
#: 4,300 the parser itself raises), floats that overflow to infinity, NaN.
_big_numbers = st.builds(
    lambda command, number: (
        b'{"id":"n","command":"' + command.encode() + b'","args":{"a":' + number + b"}}"
    ),
    _commands,
    st.integers(41, 6000).map(lambda n: b"9" * n)
    | st.integers(41, 6000).map(lambda n: b"-" + b"1" * n)
    | st.sampled_from([b"1e999", b"-1e400", b"NaN", b"Infinity", b"-Infinity"]),
)
#: Paths the daemon might open: with a NUL byte, devices that never end, a FIFO (made by
#: the test), a path under a file; each with a plan that compiles, so the path is reached.
_SPECIAL_PATHS = ["/dev/zero", "/dev/zero/x.zarr", "/proc/self/mem", "fifo", "fifo/x.zarr"]
_paths = st.sampled_from(_SPECIAL_PATHS) | st.text(max_size=8).map(lambda t: f"{t}\x00{t}.zarr")
_path_requests = st.builds(
    lambda command, path: json.dumps(
        {
            "id": "p",
            "command": command,
            "args": {"archive": path} | ({"plan_toml": LAMP_PLAN} if command == "submit" else {}),
        }
    ).encode(),
    st.sampled_from(["submit", "resume"]),
    _paths,
)
_messages = st.lists(
    st.binary(max_size=64)
    | _json.map(lambda v: json.dumps(v).encode())
    | _envelope
    | (st.integers(1, 3000) | st.integers(MAX_JSON_DEPTH + 1, 3000)).map(
        lambda n: b"[" * n + b"]" * (n % 7)
    )
    | _big_numbers
    | _path_requests,
    min_size=1,
    max_size=3,
)


def test_fuzzed_control_messages_then_a_normal_session(config, rig, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # anything a message could create lands here
    os.mkfifo(tmp_path / "fifo")  # a relative path in _SPECIAL_PATHS: no reader, ever
    with running_daemon(config, rig) as endpoints:
        ctx = zmq.Context()
        dealer = ctx.socket(zmq.DEALER)
        dealer.linger = 0
        dealer.connect(endpoints.control)
        codes = set()

        @fuzz(
            database=None,
            suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
        )
        @given(_messages)
        # One of each refusal the test counts on, whatever the profile's budget.
        @example([b"not json"])
        @example([json.dumps({"id": "x", "command": "status", "args": {"x": 1}}).encode()])
        @example([b'{"a":' + b"[" * MAX_JSON_DEPTH + b"]" * MAX_JSON_DEPTH + b"}"])
        def one_message(parts):
            dealer.send_multipart([b"", *parts])
            assert dealer.poll(10_000), f"no reply to {parts!r:.200}"
            envelope, body = dealer.recv_multipart()
            reply = json.loads(body)
            assert envelope == b"" and set(reply) == {
                "id",
                "ok",
                "result" if reply["ok"] else "error",
            }
            if not reply["ok"]:
                codes.add(reply["error"]["code"])
                assert reply["error"]["message"]

        try:
            one_message()
        finally:
            dealer.close(linger=0)
            ctx.term()
        assert {"malformed", "invalid", "too_deep"} <= codes
        assert "internal" not in codes
        _finishes_a_session(endpoints, tmp_path / "after.zarr")


def test_the_daemon_answers_while_a_large_plan_compiles(config, rig, tmp_path):
    big = '[sample]\nname = "big"\n[captures.btf]\nviews = "H1"\n'
    big += "lights = {theta_deg = 40, count = 24}\n"  # 1,944 pairs: seconds to compile
    with running_daemon(config, rig) as endpoints:
        ctx = zmq.Context()
        submitter = ctx.socket(zmq.DEALER)
        submitter.linger = 0
        try:
            submitter.connect(endpoints.control)
            args = {"plan_toml": big, "archive": str(tmp_path / "big.zarr")}
            submitter.send_multipart([b"", _request("submit", **args)])
            with DaemonClient(endpoints, timeout_s=5.0) as client:
                while (status := client.request("status"))["preparing"] is None:
                    assert status["state"] == "idle", "the plan compiled before it was asked"
                with pytest.raises(DaemonRequestError) as info:
                    client.request("submit", plan_toml=LAMP_PLAN, archive=str(tmp_path / "b"))
                assert info.value.code == "busy" and "being prepared" in info.value.message
                assert client.request("status")["preparing"] == "submit"
            assert submitter.poll(120_000), "no reply to the large submit"
            reply = json.loads(submitter.recv_multipart()[-1])
            assert reply["ok"] and reply["result"]["session"]["steps"] > 100
        finally:
            submitter.close(linger=0)
            ctx.term()
        assert client_abort(connect=endpoints)["state"] == "aborted"


def test_stopping_while_a_plan_compiles_ends_cleanly(config, rig, tmp_path):
    big = '[sample]\nname = "big"\n[captures.btf]\nviews = "H1"\n'
    big += "lights = {theta_deg = 40, count = 24}\n"
    with running_daemon(config, rig) as endpoints:
        ctx = zmq.Context()
        submitter = ctx.socket(zmq.DEALER)
        submitter.linger = 0
        try:
            submitter.connect(endpoints.control)
            args = {"plan_toml": big, "archive": str(tmp_path / "big.zarr")}
            submitter.send_multipart([b"", _request("submit", **args)])
            with DaemonClient(endpoints) as client:  # stop it preparing, or just started
                while not ((status := client.request("status"))["preparing"] or status["busy"]):
                    time.sleep(0.001)
        finally:
            submitter.close(linger=0)
            ctx.term()
    # running_daemon stopped the loop and joined it; the leak check finds no thread left
    with Archive.open(tmp_path / "big.zarr") as archive:
        # prepared, started, aborted at shutdown: an abort ends after the step under way,
        # so at most the first step is committed (with its frames), nothing after it
        committed = archive.committed_steps()
        assert committed in ((), (0,))
        for step in archive.step_table():
            for camera in step.cameras:
                assert archive.read_frame(step.index, camera).size > 0
