"""The simulator's camera, reached over ZeroMQ like a networked camera.

Wire format (see docs/devices.md, "Sim camera server"): the client is a DEALER
sending REQ-style ``[b"", request]`` with a JSON request ``{"op": "capture",
"request_id", "camera_id", "exposure_s", "gain", "bit_depth"}``. A frame comes
back as ``[b"", header, pixels]``: the JSON header (``request_id``,
``camera_id``, ``seq``, ``timestamp``, ``exposure_s``, ``gain``, ``bit_depth``,
``dtype``, ``shape``, ``crc32``) and the raw C-order little-endian buffer. An
error comes back as ``[b"", {"request_id", "error", "field"}]``. Replies to
older requests (late answers to a capture that timed out) are discarded by
``request_id``; never unpickled, sizes bounded. A ``{"request_id", "busy": true}``
note (the server is still rendering) restarts the wait: the timeout is for a
silent server, however long the simulator takes to render.
"""

from __future__ import annotations

import itertools
import json
import logging
import zlib

import numpy as np
import zmq

from drivers._lock import DeviceLock
from drivers.camera._checks import check_image, dtype_for, expected_shape, updated_settings
from drivers.camera._interface import CameraSettings, Frame, RetriedCapture
from drivers.errors import DeviceError, DeviceTimeout, ProtocolError
from rig.clock import Clock
from rig.config import CameraSpec

__all__ = ["SimCamera"]

log = logging.getLogger(__name__)

_MAX_HEADER_BYTES = 4096
_HEADER_FIELDS = {
    "request_id": int,
    "camera_id": str,
    "seq": int,
    "timestamp": float,
    "exposure_s": float,
    "gain": float,
    "bit_depth": int,
    "dtype": str,
    "shape": list,
    "crc32": int,
}


class SimCamera(RetriedCapture):
    """A camera of the simulated rig; ``spec.connection.url`` is the server's address."""

    def __init__(self, spec: CameraSpec, *, clock: Clock, context: zmq.Context | None = None):
        self.spec = spec
        self.camera_id = spec.id
        self.clock = clock
        self.retry = spec.connection.retry
        self.device = f"camera {spec.id} (sim {spec.connection.url})"
        self.settings = CameraSettings(exposure_s=0.01, gain=1.0, bit_depth=spec.bit_depth)
        # one server serves every camera: the device is the camera at that server
        self._lock = DeviceLock(f"sim camera {spec.connection.url} {spec.id}", device=self.device)
        self._own_context = context is None
        self._context = zmq.Context() if context is None else context
        self._socket = self._context.socket(zmq.DEALER)
        self._socket.setsockopt(zmq.LINGER, 0)
        self._socket.connect(spec.connection.url)
        self._request_ids = itertools.count(1)

    def configure(
        self,
        *,
        exposure_s: float | None = None,
        gain: float | None = None,
        bit_depth: int | None = None,
    ) -> CameraSettings:
        """Set exposure, gain and bit depth (the sim camera's bit depth is its spec's)."""
        self.settings = updated_settings(
            self.device,
            self.settings,
            exposure_s=exposure_s,
            gain=gain,
            bit_depth=bit_depth,
            bit_depths=(self.spec.bit_depth,),
        )
        return self.settings

    def _capture_once(self) -> Frame:
        request_id = next(self._request_ids)
        request = {
            "op": "capture",
            "request_id": request_id,
            "camera_id": self.camera_id,
            "exposure_s": self.settings.exposure_s,
            "gain": self.settings.gain,
            "bit_depth": self.settings.bit_depth,
        }
        self._socket.send_multipart([b"", json.dumps(request).encode()])
        # The exposure and readout take time on the server before the reply.
        timeout_s = self.retry.timeout_s + self.settings.exposure_s + self.spec.readout_s
        while True:
            if not self._socket.poll(round(timeout_s * 1000), zmq.POLLIN):
                raise DeviceTimeout(
                    self.device, "capture", f"no frame within {timeout_s:.3f} s (dropped)"
                )
            parts = self._socket.recv_multipart(copy=False)
            header = self._header(parts)
            if header.get("busy") is True:  # still rendering: silence, not render time, times out
                continue
            if header.get("request_id") != request_id:
                log.info("%s: discarding a late reply to request %s", self.device, header)
                continue
            return self._frame(header, parts)

    def _header(self, parts: list) -> dict:
        if len(parts) not in (2, 3) or len(parts[0]) != 0:
            raise ProtocolError(self.device, "capture", f"reply has {len(parts)} frames")
        raw = parts[1].bytes
        if len(raw) > _MAX_HEADER_BYTES:
            raise ProtocolError(self.device, "capture", f"reply header of {len(raw)} bytes")
        try:
            header = json.loads(raw)
        except (UnicodeDecodeError, json.JSONDecodeError) as err:
            raise ProtocolError(self.device, "capture", f"reply header is not JSON: {err}") from err
        if not isinstance(header, dict):
            raise ProtocolError(self.device, "capture", "reply header is not a JSON object")
        return header

    def _frame(self, header: dict, parts: list) -> Frame:
        if "error" in header:
            raise DeviceError(
                self.device,
                "capture",
                f"the camera server refused: {header['error']} (field {header.get('field')})",
            )
        for name, kind in _HEADER_FIELDS.items():
            value = header.get(name)
            if kind is float and isinstance(value, int):
                value = float(value)
            if not isinstance(value, kind) or isinstance(value, bool):
                raise ProtocolError(
                    self.device, "capture", f"reply header field {name}={value!r} is not {kind}"
                )
        if len(parts) != 3:
            raise ProtocolError(self.device, "capture", "frame header without a pixel buffer")
        if header["camera_id"] != self.camera_id:
            raise ProtocolError(
                self.device, "capture", f"the frame is from camera {header['camera_id']!r}"
            )
        dtype = dtype_for(self.settings.bit_depth)
        shape = tuple(header["shape"])
        if header["dtype"] != dtype.name or shape != expected_shape(self.spec):
            raise ProtocolError(
                self.device,
                "capture",
                f"frame is {header['dtype']} {shape}; the spec says "
                f"{dtype.name} {expected_shape(self.spec)}",
            )
        buffer = parts[2].buffer
        if buffer.nbytes != int(np.prod(shape)) * dtype.itemsize:
            raise ProtocolError(
                self.device, "capture", f"pixel buffer of {buffer.nbytes} bytes for {shape}"
            )
        crc = zlib.crc32(buffer)
        if crc != header["crc32"]:
            raise ProtocolError(
                self.device,
                "capture",
                f"frame {header['seq']} is corrupt: crc32 {crc:#010x} != {header['crc32']:#010x}",
            )
        image = np.frombuffer(buffer, dtype=dtype.newbyteorder("<")).astype(dtype).reshape(shape)
        check_image(self.device, image, self.spec, self.settings.bit_depth)
        return Frame(
            image=image,
            timestamp=float(header["timestamp"]),
            exposure_s=float(header["exposure_s"]),
            gain=float(header["gain"]),
            sequence=header["seq"],
            camera_id=header["camera_id"],
        )

    def close(self) -> None:
        """Close the socket (and the context if this camera made it); idempotent."""
        if self._socket.closed:
            return
        self._socket.close(linger=0)
        if self._own_context:
            self._context.term()
        self._lock.release()
