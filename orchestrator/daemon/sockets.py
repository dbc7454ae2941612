"""The daemon's four sockets on one ZeroMQ context: made, bound and closed together.

Control (ROUTER), events (PUB), frames (PUSH) and results (PULL), each with
``linger = 0`` and a size limit where messages come in; CURVE servers when the
settings name a secret key (read before any socket exists, so a bad key file
leaves nothing open). A socket whose setup fails is closed at once: one left open
would keep ``ctx.term()`` waiting forever.
"""

from __future__ import annotations

import logging

import zmq

from orchestrator.wire.endpoints import DaemonSettings, Endpoints
from orchestrator.wire.protocol import MAX_CONTROL_BYTES, MAX_FRAME_BYTES

__all__ = ["RECV_BATCH", "DaemonSockets"]

log = logging.getLogger(__name__)

#: Messages taken from one socket per loop turn, so no socket starves the others.
RECV_BATCH = 64


class DaemonSockets:
    """``bind()`` makes and binds the sockets (``control``, ``events``, ``frames``,
    ``results``) and returns where they listen; ``close()`` closes all (idempotent)."""

    def __init__(self, settings: DaemonSettings):
        self.settings = settings
        self.control = self.events = self.frames = self.results = None
        self._ctx: zmq.Context | None = None
        self._auth = None
        self._curve_keys: tuple[bytes, bytes] | None = None

    @property
    def bound(self) -> bool:
        return self._ctx is not None

    def bind(self) -> Endpoints:
        self._curve_keys = self.settings.curve_keys()  # a bad key file: before any socket
        self._ctx = zmq.Context()
        try:
            # A part a little over the limit still gets a reply saying so; a larger one
            # makes ZeroMQ drop the sender before it holds the message in memory.
            self.control = self._socket(zmq.ROUTER, maxmsgsize=MAX_CONTROL_BYTES + 65536)
            self.events = self._socket(zmq.PUB)
            self.frames = self._socket(zmq.PUSH)
            self.results = self._socket(zmq.PULL, maxmsgsize=MAX_FRAME_BYTES)
            urls = self.settings.bind_urls()
            sockets = {
                "control": self.control,
                "events": self.events,
                "frames": self.frames,
                "results": self.results,
            }
            for role, sock in sockets.items():
                sock.bind(urls[role])
            bound = {r: s.getsockopt_string(zmq.LAST_ENDPOINT) for r, s in sockets.items()}
        except BaseException:
            self.close()
            raise
        endpoints = Endpoints(**bound)
        log.info("daemon listening: %s", endpoints)
        return endpoints

    def _socket(self, kind: int, *, maxmsgsize: int = -1) -> zmq.Socket:
        sock = self._ctx.socket(kind)
        sock.linger = 0
        try:
            sock.maxmsgsize = maxmsgsize
            if self._curve_keys is not None:
                self._curve_server(sock, *self._curve_keys)
        except BaseException:
            sock.close(linger=0)
            raise
        return sock

    def _curve_server(self, sock: zmq.Socket, public: bytes, secret: bytes) -> None:
        from zmq.auth.thread import ThreadAuthenticator

        if self._auth is None:
            self._auth = ThreadAuthenticator(self._ctx)
            self._auth.start()
            self._auth.configure_curve(domain="*", location=str(self.settings.curve_clients_dir))
        sock.curve_secretkey = secret
        sock.curve_publickey = public
        sock.curve_server = True

    def close(self) -> None:
        for role in ("control", "events", "frames", "results"):
            sock = getattr(self, role)
            if sock is not None:
                sock.close(linger=0)
                setattr(self, role, None)
        if self._auth is not None:
            self._auth.stop()
            self._auth = None
        if self._ctx is not None:
            self._ctx.term()
            self._ctx = None
