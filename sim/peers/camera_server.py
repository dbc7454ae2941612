"""The simulated rig's cameras as a ZeroMQ server that renders from the World.

Protocol (written down in docs/devices.md, "Sim camera server"): a ROUTER on
TCP loopback (ephemeral port by default) takes REQ-style requests
``[identity, b"", request]`` where ``request`` is a JSON object (≤ 4096 bytes)
with exactly the fields ``op`` ("capture"), ``request_id`` (int ≥ 0),
``camera_id`` (a camera of the rig config), ``exposure_s`` (0 < s ≤ 60),
``gain`` (0 < g ≤ 64, linear) and ``bit_depth`` (the camera's). It answers
``[identity, b"", header, pixels]``: a JSON header (``request_id``,
``camera_id``, ``seq``, ``timestamp``, ``exposure_s``, ``gain``,
``bit_depth``, ``dtype``, ``shape``, ``crc32`` of the pixel buffer) and the raw
C-order little-endian buffer, sent with ``copy=False``; or, for a bad request,
``[identity, b"", {"request_id", "error", "field"}]`` naming the bad field.
While a frame renders longer than ``BUSY_INTERVAL_S`` (wall time), the server
sends ``[identity, b"", {"request_id", "busy": true}]`` every ``BUSY_INTERVAL_S``
before the frame, so a client's timeout covers silence, not the render.

A capture takes the World's snapshot at the start of the exposure, renders it
through ``render(camera_id, snapshot, exposure_s)`` (an integer image at the
camera's bit depth), applies the gain digitally (saturating), and lets the
exposure plus the camera's readout time pass on the world clock.
"""

from __future__ import annotations

import json
import logging
import threading
import zlib
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor, wait
from dataclasses import dataclass

import numpy as np
import zmq

from rig.config import CameraSpec
from sim.world import World, WorldSnapshot

__all__ = ["CameraFaults", "CameraServer", "RenderFn"]

log = logging.getLogger(__name__)

RenderFn = Callable[[str, WorldSnapshot, float], np.ndarray]

MAX_REQUEST_BYTES = 4096
BUSY_INTERVAL_S = 0.1  # wall time between "busy" notes while a frame renders
_MAX_EXPOSURE_S = 60.0
_MAX_GAIN = 64.0
_FIELDS = ("op", "request_id", "camera_id", "exposure_s", "gain", "bit_depth")


class RequestError(ValueError):
    """A request the server refuses; ``field`` names the culprit."""

    def __init__(self, field: str | None, message: str):
        super().__init__(message)
        self.field = field


@dataclass
class CameraFaults:
    """Faults for the next so many frames (of ``camera_id``, or of any camera if None).

    ``dropped_frames``: exposed but never sent. ``corrupt_frames``: bytes flipped
    after the crc32 was computed. ``wrong_size_frames``: one row short.
    """

    dropped_frames: int = 0
    corrupt_frames: int = 0
    wrong_size_frames: int = 0
    camera_id: str | None = None


def _request_id(message: list[bytes]):
    """The request's ``request_id`` for a busy note, None where it has none."""
    try:
        return json.loads(message[-1]).get("request_id")
    except (ValueError, AttributeError):  # not JSON, or not an object: refused anyway
        return None


def _number(request: dict, name: str, low: float, high: float) -> float:
    value = request[name]
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise RequestError(name, f"{name} must be a number, got {value!r}")
    if not low < value <= high:
        raise RequestError(name, f"{name}={value} is outside ({low}, {high}]")
    return float(value)


class CameraServer:
    """Serve every camera of ``world.config`` from one thread; ``start``/``close``.

    Parameters
    ----------
    world : the simulated rig's state and clock.
    render : ``render(camera_id, snapshot, exposure_s) -> image``; the image must be
        the camera's ``(height, width[, 3])`` in uint8 (8 bit) or uint16.
    host, port : where to bind; port 0 picks a free one (see ``url``).
    """

    def __init__(
        self,
        world: World,
        render: RenderFn,
        *,
        host: str = "127.0.0.1",
        port: int = 0,
        faults: CameraFaults | None = None,
    ):
        self.world = world
        self.render = render
        self.faults = faults or CameraFaults()
        self.frames_exposed = 0
        self._sequence: dict[str, int] = {}
        self._context = zmq.Context()
        self._socket = self._context.socket(zmq.ROUTER)
        self._socket.setsockopt(zmq.LINGER, 0)
        if port == 0:
            self.port = self._socket.bind_to_random_port(f"tcp://{host}")
        else:
            self._socket.bind(f"tcp://{host}:{port}")
            self.port = port
        self.url = f"tcp://{host}:{self.port}"
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, name="camera-server", daemon=True)

    def start(self) -> CameraServer:
        self._thread.start()
        return self

    def __enter__(self) -> CameraServer:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        """Stop the thread, close the socket and the context; idempotent."""
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout=5)
        if not self._socket.closed:
            self._socket.close(linger=0)
            self._context.term()

    def _serve(self) -> None:
        # Renders run on their own thread so that this one can say the camera is
        # busy: a slow render is the simulator's time, not a frame lost on the wire.
        with ThreadPoolExecutor(1, thread_name_prefix="camera-render") as renderer:
            while not self._stop.is_set():
                if not self._socket.poll(50, zmq.POLLIN):
                    continue
                parts = self._socket.recv_multipart()
                identity, message = parts[0], parts[1:]
                answer = renderer.submit(self._answer, message)
                while not wait([answer], timeout=BUSY_INTERVAL_S).done:
                    busy = {"request_id": _request_id(message), "busy": True}
                    self._socket.send_multipart([identity, b"", json.dumps(busy).encode()])
                reply = answer.result()
                if reply is not None:
                    self._socket.send_multipart([identity, b"", *reply], copy=False)

    def _answer(self, message: list[bytes]) -> list | None:
        request_id = None
        try:
            if len(message) != 2 or message[0] != b"":
                raise RequestError(None, f"expected [b'', request], got {len(message)} frames")
            request = self._parse(message[1])
            request_id = request.get("request_id")
            if isinstance(request_id, bool) or not isinstance(request_id, int) or request_id < 0:
                request_id = None
                raise RequestError(
                    "request_id",
                    f"request_id must be an int ≥ 0, got {request.get('request_id')!r}",
                )
            self._validate(request)
            return self._capture(request)
        except RequestError as err:
            log.info("camera server: refused a request: %s", err)
            error = {"request_id": request_id, "error": str(err), "field": err.field}
            return [json.dumps(error).encode()]

    def _parse(self, raw: bytes) -> dict:
        if len(raw) > MAX_REQUEST_BYTES:
            raise RequestError(None, f"request of {len(raw)} bytes exceeds {MAX_REQUEST_BYTES}")
        try:
            request = json.loads(raw)
        except (UnicodeDecodeError, json.JSONDecodeError) as err:
            raise RequestError(None, f"request is not JSON: {err}") from err
        if not isinstance(request, dict):
            raise RequestError(None, "request must be a JSON object")
        return request

    def _validate(self, request: dict) -> None:
        for name in request:
            if name not in _FIELDS:
                raise RequestError(name, f"unknown field {name!r}; valid are {list(_FIELDS)}")
        for name in _FIELDS:
            if name not in request:
                raise RequestError(name, f"missing field {name!r}")
        if request["op"] != "capture":
            raise RequestError("op", f"op {request['op']!r} is unknown; valid is 'capture'")
        spec = self._spec(request["camera_id"])
        _number(request, "exposure_s", 0.0, _MAX_EXPOSURE_S)
        _number(request, "gain", 0.0, _MAX_GAIN)
        if request["bit_depth"] != spec.bit_depth:
            raise RequestError(
                "bit_depth",
                f"bit_depth={request['bit_depth']!r}; camera {spec.id} has {spec.bit_depth}",
            )

    def _spec(self, camera_id) -> CameraSpec:
        cameras = {cam.id: cam for cam in self.world.config.camera_arc.cameras}
        if not isinstance(camera_id, str) or camera_id not in cameras:
            raise RequestError(
                "camera_id", f"camera_id {camera_id!r} is unknown; valid are {sorted(cameras)}"
            )
        return cameras[camera_id]

    def _take_fault(self, camera_id: str, kind: str) -> bool:
        if self.faults.camera_id not in (None, camera_id) or getattr(self.faults, kind) <= 0:
            return False
        setattr(self.faults, kind, getattr(self.faults, kind) - 1)
        return True

    def _capture(self, request: dict) -> list | None:
        spec = self._spec(request["camera_id"])
        exposure_s, gain = float(request["exposure_s"]), float(request["gain"])
        with self.world.clock.lane(spec.id):  # each camera exposes on its own time line
            snapshot = self.world.snapshot()
            image = self._render(spec, snapshot, exposure_s, gain)
            self.world.clock.sleep(exposure_s + spec.readout_s)
        seq = self._sequence.get(spec.id, 0)
        self._sequence[spec.id] = seq + 1
        self.frames_exposed += 1
        if self._take_fault(spec.id, "dropped_frames"):
            log.info("camera server: dropping frame %d of %s", seq, spec.id)
            return None
        if self._take_fault(spec.id, "wrong_size_frames"):
            image = np.ascontiguousarray(image[:-1])
        pixels = bytearray(image.astype(image.dtype.newbyteorder("<"), copy=False).tobytes())
        header = {
            "request_id": request["request_id"],
            "camera_id": spec.id,
            "seq": seq,
            "timestamp": snapshot.t,
            "exposure_s": exposure_s,
            "gain": gain,
            "bit_depth": spec.bit_depth,
            "dtype": image.dtype.name,
            "shape": list(image.shape),
            "crc32": zlib.crc32(pixels),
        }
        if self._take_fault(spec.id, "corrupt_frames"):
            pixels[len(pixels) // 2] ^= 0xFF
        return [json.dumps(header).encode(), memoryview(pixels)]

    def _render(
        self, spec: CameraSpec, snapshot: WorldSnapshot, exposure_s: float, gain: float
    ) -> np.ndarray:
        image = np.asarray(self.render(spec.id, snapshot, exposure_s))
        shape = (spec.height, spec.width) if spec.channels == 1 else (spec.height, spec.width, 3)
        dtype = np.dtype(np.uint8 if spec.bit_depth == 8 else np.uint16)
        if image.shape != shape or image.dtype != dtype:
            raise RequestError(
                "render",
                f"the renderer returned {image.dtype} {image.shape} for camera {spec.id}; "
                f"its spec needs {dtype} {shape}",
            )
        if gain != 1.0:
            top = (1 << spec.bit_depth) - 1
            image = np.clip(np.rint(image * gain), 0, top).astype(dtype)
        return image
