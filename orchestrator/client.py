"""Talking to a running daemon: requests with Lazy-Pirate retries, and following its events.

``DaemonClient.request`` sends one JSON request on a REQ socket and waits
``timeout_s`` for the reply; with no reply it closes the socket, opens a new
one and sends the same request again (same id: the daemon answers a repeat
from its reply cache without doing it twice), up to ``retries`` times, then
raises ``DaemonUnreachable``. An error reply raises ``DaemonRequestError``
with the daemon's code, field and message.

The module-level functions are what the ``rig`` commands call.
"""

from __future__ import annotations

import json
import time
import uuid
from collections.abc import Callable, Iterator
from pathlib import Path

import zmq

from orchestrator.wire.endpoints import Endpoints
from orchestrator.wire.protocol import MAX_CONTROL_BYTES, decode_json
from rig.archive import Archive
from rig.errors import ConfigError, RigError

__all__ = [
    "DaemonClient",
    "DaemonRequestError",
    "DaemonRequestInvalid",
    "DaemonUnreachable",
    "abort",
    "follow",
    "pause",
    "resume",
    "shutdown",
    "status",
    "submit",
]

TERMINAL_STATES = ("done", "aborted", "failed")
#: Seconds without an event after which ``follow`` asks whether the daemon is still there.
SILENCE_S = 3.0


class DaemonUnreachable(RigError):
    """No reply from the daemon after every retry."""


class DaemonRequestError(RigError):
    """The daemon answered with an error: ``code``, ``field``, ``message``."""

    def __init__(self, command: str, error: dict):
        self.code = error.get("code")
        self.field = error.get("field")
        self.message = error.get("message")
        where = f" ({self.field})" if self.field else ""
        super().__init__(f"{command}: {self.code}{where}: {self.message}")


class DaemonRequestInvalid(DaemonRequestError, ConfigError):
    """The daemon refused what was asked as invalid: a plan the rig cannot do, a field of
    the request (``code`` ``plan_invalid`` or ``invalid``); invalid input, so the CLI
    exits 2."""


#: error codes of a reply that say the request itself was invalid
_INVALID_CODES = ("plan_invalid", "invalid")


class DaemonClient:
    """A control connection to the daemon at ``endpoints`` (close it, or use ``with``)."""

    def __init__(
        self,
        endpoints: Endpoints | str,
        *,
        timeout_s: float = 2.5,
        retries: int = 3,
        context: zmq.Context | None = None,
    ):
        self.endpoints = Endpoints.from_base(endpoints) if isinstance(endpoints, str) else endpoints
        self.timeout_s = timeout_s
        self.retries = retries
        self._own_context = context is None
        self._ctx = context or zmq.Context()
        self._sock: zmq.Socket | None = None

    def _connect(self) -> zmq.Socket:
        sock = self._ctx.socket(zmq.REQ)
        sock.linger = 0
        self.endpoints.secure(sock)
        sock.connect(self.endpoints.control)
        return sock

    def request(self, command: str, **args) -> dict:
        """Send ``command`` with ``args``; the reply's result, or raise."""
        rid = uuid.uuid4().hex
        body = json.dumps({"id": rid, "command": command, "args": args}).encode()
        if len(body) > MAX_CONTROL_BYTES:  # the daemon would drop it unanswered
            raise DaemonRequestError(
                command,
                {"code": "too_large", "message": f"the request has {len(body)} bytes; the "
                 f"daemon takes at most {MAX_CONTROL_BYTES} bytes per message"},
            )  # fmt: skip
        reply = self.request_raw([body], expect_id=rid)
        if not reply.get("ok"):
            error = reply.get("error") or {}
            invalid = error.get("code") in _INVALID_CODES
            raise (DaemonRequestInvalid if invalid else DaemonRequestError)(command, error)
        return reply.get("result") or {}

    def request_raw(self, parts: list[bytes], *, expect_id: str | None = None) -> dict:
        """Send raw body parts (tests send malformed ones); the decoded reply."""
        for _ in range(self.retries + 1):
            if self._sock is None:
                self._sock = self._connect()
            self._sock.send_multipart(parts)
            if self._sock.poll(int(self.timeout_s * 1000), zmq.POLLIN):
                reply = decode_json(
                    self._sock.recv(), limit=MAX_CONTROL_BYTES, what="the daemon's reply"
                )
                if expect_id is None or reply.get("id") == expect_id:
                    return reply
            # Lazy Pirate: a REQ socket that lost its reply is stuck; start afresh.
            self._sock.close(linger=0)
            self._sock = None
        hint = (
            "a daemon with CURVE keys answers only clients that give --curve-server-key "
            "and --curve-secret-key"
            if self.endpoints.keys is None
            else "is this client's public certificate in its --curve-clients-dir?"
        )
        raise DaemonUnreachable(
            f"no reply from the daemon at {self.endpoints.control} after "
            f"{self.retries + 1} tries of {self.timeout_s} s; is `rig daemon` running? ({hint})"
        )

    def close(self) -> None:
        if self._sock is not None:
            self._sock.close(linger=0)
            self._sock = None
        if self._own_context:
            self._ctx.term()

    def __enter__(self) -> DaemonClient:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


#: How long ``submit`` and ``resume ARCHIVE`` wait for their reply: the daemon compiles
#: the plan first (a minute or more for the largest plans it takes, on a busy machine).
PREPARE_TIMEOUT_S = 300.0


def _one(connect: Endpoints | str, command: str, **args) -> dict:
    with DaemonClient(connect) as client:
        return client.request(command, **args)


def _prepared(connect: Endpoints | str, command: str, **args) -> dict:
    """A request that makes a session: a missing daemon is found out in seconds, a
    large plan gets the time it needs to compile."""
    with DaemonClient(connect) as client:
        client.request("status")
        client.timeout_s, client.retries = PREPARE_TIMEOUT_S, 1
        return client.request(command, **args)


def submit(
    plan: str | Path, *, archive: str | Path | None = None, connect="tcp://127.0.0.1"
) -> dict:
    """Send the plan file's text; the archive path defaults to the plan's, from here."""
    from rig.plan import load_plan

    plan = Path(plan)
    parsed = load_plan(plan)  # bad plans are reported here, before the daemon sees them
    target = Path(archive) if archive is not None else parsed.archive_path()
    return _prepared(
        connect,
        "submit",
        plan_toml=plan.read_text(),
        source=str(plan),
        archive=str(target.resolve()),
    )


def status(*, connect="tcp://127.0.0.1") -> dict:
    return _one(connect, "status")


def pause(*, connect="tcp://127.0.0.1") -> dict:
    return _one(connect, "pause")


def resume(
    archive: str | Path | None = None,
    *,
    config: str | Path | None = None,
    connect="tcp://127.0.0.1",
) -> dict:
    """Resume the paused session, or (with ``archive``) continue a crashed one.

    ``config``: a rig config TOML whose connections the resumed session uses (the
    devices moved to other ports); its geometry must be the recorded one. Default:
    the daemon's own config. An archive this machine sees is checked first: a finished
    session's is refused.
    """
    if archive is None:
        if config is not None:
            raise ConfigError("a rig config goes with an archive to resume; give ARCHIVE too")
        return _one(connect, "resume")
    path = Path(archive).resolve()
    if path.is_dir():  # the daemon checks again, for archives only it sees
        with Archive.open(path, mode="r") as recorded:
            recorded.check_resumable()
    args = {"archive": str(path)}
    if config is not None:
        from rig.config import load_rig_config

        load_rig_config(config)  # a bad file is reported here, naming it
        args.update(config_toml=Path(config).read_text(), config_source=str(config))
    return _prepared(connect, "resume", **args)


def abort(*, connect="tcp://127.0.0.1", timeout_s: float = 60.0) -> dict:
    """Abort the session; returns once its thread let go of the devices (a step under way
    ends first), so a submit right after is taken."""
    _one(connect, "abort")
    return wait_for_state(connect, TERMINAL_STATES, settled=True, timeout_s=timeout_s)


def shutdown(*, connect="tcp://127.0.0.1") -> dict:
    return _one(connect, "shutdown")


def follow(
    connect: Endpoints | str = "tcp://127.0.0.1",
    *,
    until: Callable[[dict], bool] | None = None,
    timeout_s: float | None = None,
    context: zmq.Context | None = None,
) -> Iterator[dict]:
    """Yield the daemon's events (dicts with ``topic`` and ``seq``) as they come.

    Starts with a ``status`` reply so a late joiner knows where things stand;
    stops after an event for which ``until(event)`` is true, or after
    ``timeout_s`` without any event (``DaemonUnreachable``). Without
    ``timeout_s``, a silence of ``SILENCE_S`` (the daemon publishes its status
    every second) is answered by asking for the status, which is yielded; a
    daemon that does not answer either is gone: ``DaemonUnreachable``. A gap
    in ``seq`` (slow subscriber) is reported as an event with topic ``gap``.
    """
    endpoints = Endpoints.from_base(connect) if isinstance(connect, str) else connect
    ctx = context or zmq.Context()
    sub = ctx.socket(zmq.SUB)
    sub.linger = 0
    try:
        sub.subscribe(b"")
        endpoints.secure(sub)
        sub.connect(endpoints.events)
        with DaemonClient(endpoints, context=ctx) as client:
            yield from _events(sub, client, until, timeout_s)
    finally:
        sub.close(linger=0)
        if context is None:
            ctx.term()


def _events(sub, client: DaemonClient, until, timeout_s: float | None) -> Iterator[dict]:
    last_seq = None
    event = {"topic": "status", "seq": None, **client.request("status")}
    while True:
        seq = event.get("seq")
        if isinstance(seq, int):  # a status asked for has none
            if last_seq is not None and seq != last_seq + 1:
                yield {"topic": "gap", "seq": seq, "missed": seq - last_seq - 1}
            last_seq = seq
        yield event
        if until is not None and until(event):
            return
        wait = SILENCE_S if timeout_s is None else timeout_s
        if sub.poll(int(wait * 1000)):
            _topic, body = sub.recv_multipart()
            event = decode_json(body, limit=MAX_CONTROL_BYTES, what="an event")
            continue
        if timeout_s is not None:
            raise DaemonUnreachable(f"no event from {client.endpoints.events} for {timeout_s} s")
        try:
            event = {"topic": "status", "seq": None, **client.request("status")}
        except DaemonUnreachable as err:
            raise DaemonUnreachable(
                f"the daemon is unreachable: no event for {SILENCE_S:g} s, and {err}"
            ) from err


def session_paused(event: dict) -> bool:
    """For ``follow(until=...)``: the session paused (a fault, or ``rig pause``)."""
    if event.get("topic") == "state":
        return event.get("to") == "paused"
    return event.get("topic") == "status" and event.get("state") == "paused"


def session_ended(event: dict) -> bool:
    """For ``follow(until=...)``: the session reached done, aborted or failed."""
    if event.get("topic") == "state":
        return event.get("to") in TERMINAL_STATES
    if event.get("topic") == "status":  # a late joiner's first look
        return event.get("state") in TERMINAL_STATES and not event.get("busy")
    return False


def wait_for_state(
    connect, states: tuple[str, ...], *, timeout_s: float = 30.0, settled: bool = False
) -> dict:
    """Poll ``status`` until the daemon's state is one of ``states``; the status.

    With ``settled``, also until no session thread holds the devices any more.
    """
    deadline = time.monotonic() + timeout_s
    with DaemonClient(connect) as client:
        while True:
            current = client.request("status")
            if current["state"] in states and not (settled and current["busy"]):
                return current
            if time.monotonic() > deadline:
                still = "busy (its session thread still holds the devices)"
                if current["state"] not in states:
                    still = f"{current['state']}, not one of {list(states)}"
                raise DaemonUnreachable(f"the daemon stayed {still} for {timeout_s} s")
            time.sleep(0.02)
