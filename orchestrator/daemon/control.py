"""The control boundary: every request gets one reply, whatever handling it raised.

``as_message_error`` turns any exception into the error reply's code, field and
message, naming the request; ``split_envelope`` separates a ROUTER message's
routing frames from its body. A ``Preparation`` makes a session (validate the
plan, compile it, create the archive) on its own thread, because compiling a
large plan (thousands of view and light pairs, each an inverse-kinematics solve)
takes seconds to a minute and the loop must go on answering meanwhile; the loop
polls ``done`` each turn and sends the one reply to every client that asked (a
Lazy-Pirate retry of the same request joins the first).
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from dataclasses import dataclass, field

import zmq

from orchestrator.daemon.admission import SessionError
from orchestrator.daemon.session import Session
from orchestrator.daemon.state import IllegalTransition
from orchestrator.wire.protocol import MessageError
from rig.errors import PlanError, RigError

__all__ = ["Preparation", "as_message_error", "split_envelope"]

log = logging.getLogger(__name__)


def split_envelope(parts: list[zmq.Frame]) -> tuple[list[zmq.Frame], list[zmq.Frame]]:
    """ROUTER parts → (routing envelope incl. the empty delimiter, body parts)."""
    for i, part in enumerate(parts[1:], 1):
        if len(part) == 0:
            return parts[: i + 1], parts[i + 1 :]
    return parts[:1], parts[1:]


def as_message_error(err: Exception, request: dict) -> MessageError:
    """The error reply for whatever handling ``request`` raised: code, field, and a
    message that names the request."""
    command = request.get("command")
    what = f"{command!r} request" if isinstance(command, str) else "the request"
    match err:
        case MessageError():
            return err
        case IllegalTransition():
            return MessageError("illegal_state", str(err), "command")
        case PlanError():
            return MessageError("plan_invalid", str(err), "args.plan_toml")
        case SessionError(field=field):
            return MessageError("rejected", str(err), field)
        case RigError():
            return MessageError("rejected", str(err))
        case MemoryError():
            return MessageError(
                "too_large", f"{what} needs more memory than this machine has; nothing was done"
            )
        case RecursionError():
            return MessageError(
                "too_deep", f"{what} nests too deeply to be handled; nothing was done"
            )
        case OSError(filename=str() as path):
            return MessageError("rejected", f"{what}: {path}: {err.strerror}")
    log.exception("%s failed unexpectedly", what)
    return MessageError(
        "internal", f"{what} failed: {type(err).__name__}: {err}; the daemon goes on"
    )


@dataclass
class Preparation:
    """``make()`` running on a thread for the request ``key`` (id, body digest)."""

    key: tuple | None
    request_id: str
    command: str
    make: Callable[[], Session]
    envelopes: list[list[zmq.Frame]] = field(default_factory=list)
    _session: Session | None = None
    _error: BaseException | None = None
    _thread: threading.Thread | None = None

    def start(self) -> Preparation:
        self._thread = threading.Thread(target=self._run, name=f"prepare-{self.command}")
        self._thread.start()
        return self

    def _run(self) -> None:
        try:
            self._session = self.make()
        except BaseException as err:  # handed to the loop, which replies with it
            self._error = err

    @property
    def done(self) -> bool:
        return not self._thread.is_alive()

    def wait(self) -> None:
        self._thread.join()

    def result(self) -> Session:
        """The session (after ``done``), or raise what making it raised."""
        self.wait()
        if self._error is not None:
            raise self._error
        return self._session
