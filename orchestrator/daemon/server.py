"""The daemon: ZeroMQ sockets around one session at a time.

One loop thread owns every socket (``sockets.DaemonSockets``): it answers the
control ROUTER, publishes events on PUB (with a sequence number each, and a
``status`` snapshot every ``status_interval_s`` for late joiners), pushes frames
to the workers and pulls their results. The session runs on its own thread and talks to the loop
through an ``Outbox`` (thread-safe queues); the loop never blocks on a socket, so
the daemon answers control requests while frames wait at the workers' HWM
(``relay.Relay`` streams the frames and takes the results back). A
new session is prepared (plan compiled, archive created) on a thread of its own
(``control.Preparation``), so a large plan does not stop the answers either.
"""

from __future__ import annotations

import hashlib
import os
import queue
import threading
import time
from collections import OrderedDict
from pathlib import Path

import zmq

from orchestrator.daemon.admission import rig_config_from_toml
from orchestrator.daemon.control import Preparation, as_message_error, split_envelope
from orchestrator.daemon.devices import build_devices
from orchestrator.daemon.relay import Relay
from orchestrator.daemon.session import DeviceFactory, Session
from orchestrator.daemon.sockets import RECV_BATCH, DaemonSockets
from orchestrator.daemon.state import (
    IllegalTransition,
    SessionEvent,
    SessionState,
    StateMachine,
    allowed_events,
)
from orchestrator.daemon.stream import Outbox
from orchestrator.wire.endpoints import DaemonSettings, Endpoints
from orchestrator.wire.protocol import (
    MAX_CONTROL_BYTES,
    MessageError,
    Request,
    decode_request,
    encode_error,
    encode_event,
    encode_reply,
    request_id,
    validate_request,
)
from rig.clock import Clock, RealClock
from rig.config import RigConfig

__all__ = ["Daemon"]

_REPLY_CACHE = 256


class Daemon:
    """Owns the devices' factory, the sockets and one session at a time.

    ``bind()`` opens the sockets and returns their ``Endpoints``; ``serve()``
    runs the loop until a ``shutdown`` request or ``stop()``, then closes all.
    """

    def __init__(
        self,
        config: RigConfig,
        *,
        settings: DaemonSettings | None = None,
        devices: DeviceFactory = build_devices,
        clock: Clock | None = None,
    ):
        self.config = config
        self.settings = settings or DaemonSettings()
        self.settings.check_exposure()
        self._devices = devices
        self.clock = clock or RealClock()
        self.machine = StateMachine(on_change=self._state_changed)
        self._outbox = Outbox(self.settings.max_in_flight)
        self._session: Session | None = None
        self._thread: threading.Thread | None = None
        self._replies: OrderedDict[tuple, bytes] = OrderedDict()
        self._seq = 0
        self._stop = threading.Event()
        self._sockets = DaemonSockets(self.settings)
        self._relay = Relay(self.settings, self._sockets, self._outbox, self._publish)
        self._preparing: Preparation | None = None
        self.endpoints: Endpoints | None = None

    # -- sockets ----------------------------------------------------------------------------

    def bind(self) -> Endpoints:
        """Create and bind the four sockets; returns where they listen."""
        self.endpoints = self._sockets.bind()
        return self.endpoints

    # -- the loop ---------------------------------------------------------------------------

    def stop(self) -> None:
        """Ask the loop to end (thread-safe); an active session is aborted first."""
        self._stop.set()

    def serve(self) -> None:
        """Run until shutdown; aborts an active session and closes every socket on the way out."""
        if not self._sockets.bound:
            self.bind()
        poller = zmq.Poller()
        poller.register(self._sockets.control, zmq.POLLIN)
        poller.register(self._sockets.results, zmq.POLLIN)
        next_status = 0.0
        try:
            while not self._stop.is_set():
                want_out = self._relay.wants_to_send()
                poller.register(self._sockets.frames, zmq.POLLOUT if want_out else 0)
                active = self._thread is not None or self._preparing is not None
                ready = dict(poller.poll(10 if active or want_out else 100))
                if ready.get(self._sockets.control):
                    self._serve_control()
                self._reply_prepared()
                if ready.get(self._sockets.results):
                    self._relay.take_results()
                self._take_frames()
                self._relay.send_frames()
                self._publish_queued()
                self._relay.check_drains()
                self._reap_session()
                now = time.monotonic()
                self._relay.report_live()
                self._relay.requeue_overdue(now)
                if now >= next_status:
                    self._publish("status", self.status())
                    next_status = now + self.settings.status_interval_s
        finally:
            if self._preparing is not None:  # a thread is compiling a plan: let it end
                self._preparing.wait()
                self._reply_prepared()
            self._shutdown_session()
            self._relay.close()
            self._publish_queued()
            self._sockets.close()

    # -- control ----------------------------------------------------------------------------

    def _serve_control(self) -> None:
        for _ in range(RECV_BATCH):
            try:
                # Frames, not bytes: an oversized message is measured and refused uncopied.
                parts = self._sockets.control.recv_multipart(zmq.NOBLOCK, copy=False)
            except zmq.Again:
                return
            envelope, body = split_envelope(parts)
            reply = self._answer(envelope, body)
            if reply is not None:  # None: a session is being prepared; it replies when ready
                self._sockets.control.send_multipart([*envelope, reply])

    def _answer(self, envelope: list[zmq.Frame], body: list[zmq.Frame]) -> bytes | None:
        """The reply to one request; every failure becomes an error reply naming the request."""
        size = sum(len(part) for part in body)
        if size > MAX_CONTROL_BYTES:
            error = MessageError(
                "too_large",
                f"the request has {size} bytes in {len(body)} part(s); "
                f"the limit is {MAX_CONTROL_BYTES} bytes per message",
            )
            return encode_error(None, error)
        if len(body) != 1:
            error = MessageError(
                "malformed", f"a request has exactly one body part, got {len(body)}"
            )
            return encode_error(None, error)
        raw = body[0].bytes
        try:
            data = decode_request(raw)
        except MessageError as err:
            return encode_error(None, err)
        rid = request_id(data)
        # A Lazy-Pirate retry (same id, same body) gets the same answer, done once.
        key = None if rid is None else (rid, hashlib.blake2b(raw, digest_size=16).digest())
        if key in self._replies:
            return self._replies[key]
        if key is not None and self._preparing is not None and self._preparing.key == key:
            self._preparing.envelopes.append(envelope)
            return None
        try:
            request = validate_request(data)
            make = self._session_maker(request)
            if make is not None:
                self._check_free(request.command)
                self._preparing = Preparation(key, request.id, request.command, make)
                self._preparing.envelopes.append(envelope)
                self._preparing.start()
                return None
            reply = encode_reply(request.id, self._dispatch(request))
        except Exception as err:
            reply = encode_error(rid, as_message_error(err, data))
        self._remember(key, reply)
        return reply

    def _remember(self, key: tuple | None, reply: bytes) -> None:
        if key is not None:
            self._replies[key] = reply
            while len(self._replies) > _REPLY_CACHE:
                self._replies.popitem(last=False)

    def _session_maker(self, request: Request):
        """For submit and resume ARCHIVE: what makes their session (off the loop)."""
        args = request.args
        options = self._session_options()
        if request.command == "submit":
            return lambda: Session.start_new(
                args.plan_toml,
                source=args.source,
                archive_path=args.archive,
                config=self.config,
                **options,
            )
        if request.command == "resume" and args.archive is not None:

            def resume() -> Session:
                config = self.config
                if args.config_toml is not None:
                    config = rig_config_from_toml(args.config_toml, source=args.config_source)
                return Session.resume_from(Path(args.archive), config=config, **options)

            return resume
        return None

    def _reply_prepared(self) -> None:
        """Start the prepared session, or report why it could not be made."""
        preparing = self._preparing
        if preparing is None or not preparing.done:
            return
        self._preparing = None
        try:
            reply = encode_reply(preparing.request_id, self._start(preparing.result()))
        except Exception as err:
            reply = encode_error(
                preparing.request_id, as_message_error(err, {"command": preparing.command})
            )
        self._remember(preparing.key, reply)
        for envelope in preparing.envelopes:
            self._sockets.control.send_multipart([*envelope, reply])

    def _dispatch(self, request: Request) -> dict:
        match request.command:
            case "status":
                return self.status()
            case "resume" | "pause":
                self.machine.fire(SessionEvent(request.command))
                return self.status()
            case "abort":
                self.machine.fire(SessionEvent.ABORT)
                self._relay.stop_streaming(self._session.id)
                return self.status()
            case "calibrate":
                raise MessageError(
                    "not_built",
                    f"calibrating {request.args.target} from the daemon is not built yet; "
                    "nothing was done (use `rig calibrate`)",
                    "command",
                )
            case "shutdown":
                self._stop.set()
                return {"stopping": True, "state": self.machine.state.value}
        raise AssertionError(request.command)

    def _check_free(self, command: str) -> None:
        if self._preparing is not None:
            raise MessageError(
                "busy",
                f"a session is being prepared ({self._preparing.command}: its plan compiles); "
                f"{command} again after it started",
                "command",
            )
        if self._thread is not None:
            raise MessageError(
                "busy",
                f"a session is {self.machine.state.value} (session {self._session.id}); "
                f"{command} again after it ends, or abort it",
                "command",
            )
        if not self.machine.can(SessionEvent.SUBMIT):
            raise IllegalTransition(self.machine.state, SessionEvent.SUBMIT)

    def _session_options(self) -> dict:
        return {
            "devices": self._devices,
            "clock": self.clock,
            "machine": self.machine,
            "outbox": self._outbox,
            "on_fault": self.settings.on_fault,
            "drain_timeout_s": self.settings.drain_timeout_s,
        }

    def _start(self, session: Session) -> dict:
        try:
            self.machine.fire(SessionEvent.SUBMIT, session=session.id)
        except IllegalTransition:
            session.archive.close()
            raise
        self._session = session
        self._relay.start_live(session.id, session.archive.material)
        self._thread = threading.Thread(target=session.run, name=f"session-{session.id}")
        self._thread.start()
        return self.status()

    def status(self) -> dict:
        """The daemon's state, the session's progress, workers and stream counts."""
        state = self.machine.state
        return {
            "state": state.value,
            "allowed": list(allowed_events(state)),
            "busy": self._thread is not None,  # a session thread still holds the devices
            "preparing": None if self._preparing is None else self._preparing.command,
            "session": None if self._session is None else self._session.status(),
            "workers": self._relay.workers_alive(),
            "stream": self._relay.counts(),
            "pid": os.getpid(),
        }

    def _state_changed(self, old, new, event, detail) -> None:
        # Any thread: queue the event for the loop, wake the session.
        change = {"from": old.value, "to": new.value, "event": event.value}
        change.update((k, v) for k, v in detail.items() if k != "session")
        self._outbox.publish("state", change)
        if self._session is not None:
            self._session.notify()

    # -- the session thread ---------------------------------------------------------------

    def _take_frames(self) -> None:
        accepting = not self._stop.is_set() and self.machine.state != SessionState.ABORTED
        self._relay.take_frames(accepting=accepting)

    def _reap_session(self) -> None:
        if self._thread is not None and not self._thread.is_alive():
            self._thread.join()
            self._thread = None
            self._publish("status", self.status())

    def _shutdown_session(self) -> None:
        if self._thread is None:
            return
        if self.machine.can(SessionEvent.ABORT):
            self.machine.fire(SessionEvent.ABORT, reason="daemon shutting down")
        while self._thread.is_alive():
            # Keep taking frames and answering drains (at once) so the session can end.
            self._relay.drain_now()
            self._take_frames()
            self._relay.check_drains()
            self._thread.join(0.01)
        self._reap_session()

    # -- events -----------------------------------------------------------------------------

    def _publish(self, topic: str, payload: dict) -> None:
        self._seq += 1
        self._sockets.events.send_multipart(encode_event(topic, self._seq, time.time(), payload))

    def _publish_queued(self) -> None:
        while True:
            try:
                topic, payload = self._outbox.events.get_nowait()
            except queue.Empty:
                return
            self._publish(topic, payload)
