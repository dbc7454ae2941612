"""The daemon's side of the workers: frames out, results back, drains answered.

A session's frames arrive through the ``Outbox`` (bounded: the session thread
waits while the loop is behind) and enter the ``FrameLedger``; they go out on the
PUSH socket to whichever worker is free and stay in the ledger until their
result comes back on the PULL socket. Results are handed to the session's
``LiveWriter``, which stores them in the archive. A worker counts as alive while
it sent anything within ``worker_timeout_s``; with none alive a frame is not
streamed (it is in the archive, and ``rig process`` covers it). A session's
``drain`` is answered once its frames have results, or at its deadline.
The relay is used by the daemon's loop thread only.
"""

from __future__ import annotations

import logging
import queue
import time
from collections.abc import Callable

import zmq

from orchestrator.daemon.live import LiveWriter
from orchestrator.daemon.sockets import RECV_BATCH, DaemonSockets
from orchestrator.daemon.stream import FrameLedger, InFlight, Outbox
from orchestrator.wire.endpoints import DaemonSettings
from orchestrator.wire.protocol import MessageError, decode_result

__all__ = ["Relay"]

log = logging.getLogger(__name__)


class Relay:
    """Streams the frames of ``outbox`` over ``sockets`` and takes the results back;
    ``publish(topic, payload)`` sends the daemon's events (log lines here)."""

    def __init__(
        self,
        settings: DaemonSettings,
        sockets: DaemonSockets,
        outbox: Outbox,
        publish: Callable[[str, dict], None],
    ):
        self.settings = settings
        self._sockets = sockets
        self._outbox = outbox
        self._publish = publish
        self._ledger = FrameLedger(resend_after_s=settings.resend_after_s)
        self._live: dict[str, LiveWriter] = {}  # session id → its results' writer
        self._workers: dict[str, float] = {}  # worker → when it was last heard
        self._not_streamed = 0
        self._drains: list[dict] = []

    # -- workers ----------------------------------------------------------------------------

    def _alive(self, last_seen: float) -> bool:
        return time.monotonic() - last_seen < self.settings.worker_timeout_s

    def workers_alive(self) -> int:
        """How many workers were heard within ``worker_timeout_s``."""
        return sum(self._alive(t) for t in self._workers.values())

    def wants_to_send(self) -> bool:
        """A frame waits and a worker is there to take it."""
        return self._ledger.next_to_send() is not None and self.workers_alive() > 0

    def counts(self) -> dict:
        """The stream's counts for the daemon's status."""
        return {
            "in_flight": self._ledger.in_flight,
            "processed": self._ledger.acked,
            "resent": self._ledger.resent,
            "duplicates": self._ledger.duplicates,
            "not_streamed": self._not_streamed,
        }

    # -- frames -----------------------------------------------------------------------------

    def start_live(self, session: str, material) -> None:
        """Store ``session``'s results in its archive's ``material`` group from now on."""
        self._live[session] = LiveWriter(material)

    def stop_streaming(self, session: str) -> None:
        """An aborted session's frames go to no worker: its thread must not wait for them."""
        dropped = self._ledger.forget(session)
        if dropped:
            self._publish("log", {"kind": "unprocessed", "session": session, "frames": dropped})

    def take_frames(self, *, accepting: bool) -> None:
        """Move the sessions' frames into the ledger; with ``accepting`` False (the daemon
        stops, or the session was aborted) or no worker alive, only count them."""
        streaming = accepting and self.workers_alive() > 0
        if streaming and any(writer.backlogged for writer in self._live.values()):
            return  # the disk is behind the workers: let the session wait
        while not streaming or self._ledger.in_flight < self.settings.max_in_flight:
            try:
                header, parts = self._outbox.frames.get_nowait()
            except queue.Empty:
                return
            if streaming:
                self._ledger.add(InFlight(header.frame_id, header.session, parts))
            else:
                self._not_streamed += 1  # in the archive; `rig process` covers it

    def send_frames(self) -> None:
        if not self.workers_alive():
            return
        while (entry := self._ledger.next_to_send()) is not None:
            try:
                self._sockets.frames.send_multipart(entry.parts, zmq.NOBLOCK, copy=False)
            except zmq.Again:
                return  # every worker's queue is full: try again when POLLOUT
            self._ledger.mark_sent(entry, time.monotonic())

    def requeue_overdue(self, now: float) -> None:
        """Frames without a result for ``resend_after_s`` go out again."""
        self._ledger.requeue_overdue(now)

    # -- results ----------------------------------------------------------------------------

    def take_results(self) -> None:
        for _ in range(RECV_BATCH):
            try:
                parts = self._sockets.results.recv_multipart(zmq.NOBLOCK, copy=False)
            except zmq.Again:
                return
            try:
                header, arrays = decode_result(parts)
            except MessageError as err:
                log.warning("bad message from a worker: %s", err)
                self._publish("log", {"kind": "worker_message", "error": err.to_json()})
                continue
            self._workers[header.worker] = time.monotonic()
            if header.kind == "error" or header.message:  # a bad frame, or a stage that failed
                problem = {"worker": header.worker, "frame_id": header.frame_id}
                self._publish("log", {"kind": "worker_error", "message": header.message, **problem})
            if header.kind != "result":
                continue
            if self._ledger.ack(header.frame_id) is None:
                continue
            writer = self._live.get(header.session)
            if writer is not None and arrays:
                writer.append(header.model_dump(), arrays)  # written on the writer's thread

    def report_live(self) -> None:
        """Publish what the live writers could not store."""
        for session, writer in self._live.items():
            self._report_live(session, writer)

    def _report_live(self, session: str, writer: LiveWriter) -> None:
        for error in writer.take_errors():
            log.warning("session %s: live results not stored: %s", session, error)
            self._publish("log", {"kind": "live_not_stored", "session": session, "error": error})

    # -- drains -----------------------------------------------------------------------------

    def check_drains(self) -> None:
        """Answer the drains whose session has all its results, or whose deadline passed."""
        while True:
            try:
                self._drains.append(self._outbox.drains.get_nowait())
            except queue.Empty:
                break
        for request in list(self._drains):
            session = request["session"]
            outstanding = self._ledger.outstanding(session)
            gave_up = time.monotonic() > request["deadline"] or not self.workers_alive()
            waiting = not self._outbox.frames.empty()  # held back while the disk caught up
            if (outstanding or waiting) and not gave_up:
                continue
            if outstanding:
                dropped = self._ledger.forget(session)
                self._publish("log", {"kind": "unprocessed", "session": session, "frames": dropped})
            writer = self._live.get(session)
            if writer is not None:
                if not writer.finish():
                    continue  # still writing: look again next turn
                self._report_live(session, writer)
                del self._live[session]
            request["stored"] = 0 if writer is None else writer.frames
            self._drains.remove(request)
            request["done"].set()

    def drain_now(self) -> None:
        """Answer every drain without waiting for results (the daemon shuts down)."""
        for request in self._drains:
            request["deadline"] = 0.0

    def close(self) -> None:
        """Close the live writers of sessions that never drained."""
        for writer in self._live.values():
            writer.close()
        self._live.clear()
