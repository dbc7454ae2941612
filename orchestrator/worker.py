"""A processing worker: pull frames from the daemon, run a stage, push the results.

``run_worker("stats", "tcp://HOST:PORT")`` connects a PULL socket to the
daemon's frames socket and a PUSH socket to its results socket. Each result
carries the frame's id, so the daemon knows which frames are done and
re-sends those of a worker that died. The worker says ``hello`` on start and
sends a heartbeat every ``heartbeat_s``: the daemon streams only while some
worker is alive. Several workers of one stage share the frames round robin.

A worker runs one or more stages (``"stats,register"``) on every frame it
pulls; frames go round robin to the workers, so every worker of a session runs
the same stages. A stage is a function ``(image, header) → dict[name, ndarray]``
in ``STAGES`` (``{}`` for frames not of its kind); the results travel as
``<stage>.<name>`` arrays and land in the archive's ``material/live/<stage>/``.
Besides ``stats``, the stages of ``processing.live``: ``register`` (btf/ps
frames rectified onto the texel grid), ``laser`` (the laser line of mdf frames),
``ps`` (a view's photometric stereo when its last lamp is in).
"""

from __future__ import annotations

import logging
import os
import threading
import time
import uuid
from collections.abc import Callable

import numpy as np
import zmq

from orchestrator.wire.endpoints import Endpoints
from orchestrator.wire.protocol import (
    MAX_FRAME_BYTES,
    MessageError,
    NamedArray,
    ResultHeader,
    decode_frame,
    encode_result,
)
from processing.live import LIVE_STAGES
from rig.errors import ConfigError

__all__ = ["STAGES", "frame_stats", "run_worker", "worker_stages"]

log = logging.getLogger(__name__)


def frame_stats(image: np.ndarray, *, saturation_level: float | None = None) -> dict:
    """Per-channel mean and saturated fraction of one frame.

    Parameters
    ----------
    image : (H, W, C) or (H, W) uint8, uint16 or float32
        A camera frame.
    saturation_level : float, optional
        Values ≥ this count as saturated; default the dtype's maximum
        (1.0 for float frames).

    Returns
    -------
    dict
        ``mean`` : (C,) float32, the channel means (in the frame's units);
        ``saturated`` : (C,) float32 in [0, 1], fraction of pixels at or above
        the saturation level.
    """
    pixels = image.reshape(image.shape[0] * image.shape[1], -1)
    if saturation_level is None:
        kind = image.dtype.kind
        saturation_level = float(np.iinfo(image.dtype).max) if kind in "ui" else 1.0
    mean = pixels.mean(axis=0, dtype=np.float64)
    saturated = (pixels >= saturation_level).mean(axis=0, dtype=np.float64)
    return {"mean": mean.astype(np.float32), "saturated": saturated.astype(np.float32)}


def _stats(image: np.ndarray, header: dict) -> dict:
    return frame_stats(image)


#: stage name → function of one frame and its header (as a dict).
STAGES: dict[str, Callable[[np.ndarray, dict], dict]] = {"stats": _stats, **LIVE_STAGES}


def worker_stages(stage: str) -> dict[str, Callable[[np.ndarray, dict], dict]]:
    """The functions of ``stage`` (comma-separated names of ``STAGES``), in order;
    ``ConfigError`` naming the unknown ones."""
    names = [n.strip() for n in stage.split(",") if n.strip()]
    unknown = [n for n in names if n not in STAGES]
    if unknown or not names:
        raise ConfigError(
            f"live stage(s) {stage!r}: unknown {unknown or stage!r}; the stages are "
            f"{sorted(STAGES)}"
        )
    return {n: STAGES[n] for n in names}


def run_worker(
    stage: str,
    connect: Endpoints | str = "tcp://127.0.0.1",
    *,
    stop: threading.Event | None = None,
    heartbeat_s: float = 0.5,
    name: str | None = None,
    max_frames: int | None = None,
) -> int:
    """Process frames until ``stop`` is set (or ``max_frames`` are done); how many.

    Raises ``ConfigError`` for an unknown stage.
    """
    functions = worker_stages(stage)
    endpoints = Endpoints.from_base(connect) if isinstance(connect, str) else connect
    worker = name or f"{os.uname().nodename}-{os.getpid()}-{uuid.uuid4().hex[:6]}"
    ctx = zmq.Context()
    frames = ctx.socket(zmq.PULL)
    results = ctx.socket(zmq.PUSH)
    done = 0
    try:
        for sock in (frames, results):
            sock.linger = 0
        frames.maxmsgsize = MAX_FRAME_BYTES + 65536
        frames.rcvhwm = 4  # few frames queued here: a dying worker takes few with it
        for sock, url in ((frames, endpoints.frames), (results, endpoints.results)):
            endpoints.secure(sock)
            sock.connect(url)
        plain = {"worker": worker, "stage": stage}
        results.send_multipart(encode_result(ResultHeader(kind="hello", **plain)))
        next_beat = time.monotonic() + heartbeat_s
        while not (stop is not None and stop.is_set()):
            if frames.poll(int(heartbeat_s * 500)):
                parts = frames.recv_multipart(copy=False)
                results.send_multipart(_process(parts, functions, plain), copy=False)
                done += 1
                if max_frames is not None and done >= max_frames:
                    break
            if time.monotonic() >= next_beat:
                results.send_multipart(encode_result(ResultHeader(kind="heartbeat", **plain)))
                next_beat = time.monotonic() + heartbeat_s
    finally:
        frames.close(linger=0)
        # Give the last results a moment to leave.
        results.close(linger=500)
        ctx.term()
    return done


def _wire(value) -> np.ndarray:
    """An array in one of the protocol's dtypes (bool → uint8, float16 → float32)."""
    a = np.asarray(value)
    if a.dtype == np.bool_:
        return a.astype(np.uint8)
    if a.dtype == np.float16:
        return a.astype(np.float32)
    return a


def _process(parts, functions: dict, plain: dict) -> list:
    try:
        header, image = decode_frame(parts)
    except MessageError as err:
        log.warning("%s: bad frame: %s", plain["worker"], err)
        return encode_result(ResultHeader(kind="error", message=str(err), **plain))
    ids = {
        "frame_id": header.frame_id,
        "session": header.session,
        "step": header.step,
        "camera": header.camera,
        "sub": header.sub,
    }
    values, problems = {}, []
    facts = header.model_dump()
    for name, function in functions.items():
        try:
            out = function(image, facts)
        except Exception as err:  # reported with the result; the frame is still acknowledged
            log.warning("%s: stage %s failed on frame %s: %s", plain["worker"], name, ids, err)
            problems.append(f"stage {name}: {type(err).__name__}: {err}"[:1000])
            continue
        values.update({f"{name}.{key}": _wire(value) for key, value in out.items()})
    try:
        specs = tuple(
            NamedArray(name=n, dtype=a.dtype.name, shape=a.shape) for n, a in values.items()
        )
        result = ResultHeader(
            kind="result", arrays=specs, message="; ".join(problems) or None, **ids, **plain
        )
    except ValueError as err:  # arrays the protocol cannot carry: report, still acknowledge
        log.warning("%s: results of frame %s not sendable: %s", plain["worker"], ids, err)
        problems.append(f"results not sendable: {err}"[:1000])
        values = {}
        result = ResultHeader(kind="result", message="; ".join(problems), **ids, **plain)
    return encode_result(result, values.values())
