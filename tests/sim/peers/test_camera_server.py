"""The camera server on its own, spoken to with a plain REQ socket: replies per
the documented wire format, and every bad request answered by an error header
that names the field, after which the server goes on."""

import json
import re
import zlib

import numpy as np
import pytest
import zmq

from rig.clock import VirtualClock
from rig.config import CameraArc, CameraSpec, RigConfig
from sim.peers.camera_server import MAX_REQUEST_BYTES, CameraServer
from sim.world import World

CAMERAS = (CameraSpec(id="cam0", theta_deg=0, width=16, height=8, channels=1, readout_s=0.1),)
GOOD = {
    "op": "capture",
    "request_id": 7,
    "camera_id": "cam0",
    "exposure_s": 0.5,
    "gain": 1.0,
    "bit_depth": 8,
}


def ramp(camera_id, snapshot, exposure_s):
    image = (np.arange(8 * 16) % 251).astype(np.uint8).reshape(8, 16)
    image[0, 0] = round(snapshot.turntable_deg)
    return image


@pytest.fixture
def world():
    return World(RigConfig(camera_arc=CameraArc(cameras=CAMERAS)), VirtualClock())


@pytest.fixture
def request_socket(world):
    with CameraServer(world, ramp) as server:
        context = zmq.Context()
        socket = context.socket(zmq.REQ)
        socket.setsockopt(zmq.LINGER, 0)
        socket.setsockopt(zmq.RCVTIMEO, 2000)
        socket.connect(server.url)
        yield socket, server
        socket.close()
        context.term()


def test_a_capture_reply_follows_the_wire_format(request_socket, world):
    socket, server = request_socket
    assert server.url.startswith("tcp://127.0.0.1:") and server.port > 0
    world.move("turntable", 33.0)
    world.clock.sleep(5.0)
    socket.send(json.dumps(GOOD).encode())
    header_raw, pixels = socket.recv_multipart()
    header = json.loads(header_raw)
    assert header == {
        "request_id": 7,
        "camera_id": "cam0",
        "seq": 0,
        "timestamp": 5.0,
        "exposure_s": 0.5,
        "gain": 1.0,
        "bit_depth": 8,
        "dtype": "uint8",
        "shape": [8, 16],
        "crc32": zlib.crc32(pixels),
    }
    image = np.frombuffer(pixels, np.uint8).reshape(8, 16)
    assert image[0, 0] == 33
    np.testing.assert_array_equal(image.ravel()[1:], np.arange(1, 128) % 251)
    assert world.clock.now() == pytest.approx(5.0 + 0.5 + 0.1)


@pytest.mark.parametrize(
    ("request_bytes", "field", "match"),
    [
        (b"\xff\xfe", None, "not JSON"),
        (b"[1, 2]", None, "JSON object"),
        (json.dumps({**GOOD, "pickle": True}).encode(), "pickle", "unknown field 'pickle'"),
        (json.dumps({k: v for k, v in GOOD.items() if k != "gain"}).encode(), "gain", "missing"),
        (json.dumps({**GOOD, "op": "shutdown"}).encode(), "op", "valid is 'capture'"),
        (json.dumps({**GOOD, "request_id": -1}).encode(), "request_id", "int ≥ 0"),
        (json.dumps({**GOOD, "camera_id": "cam9"}).encode(), "camera_id", "valid are \\['cam0'\\]"),
        (json.dumps({**GOOD, "exposure_s": 0}).encode(), "exposure_s", "outside \\(0.0, 60.0\\]"),
        (json.dumps({**GOOD, "exposure_s": "1"}).encode(), "exposure_s", "must be a number"),
        (json.dumps({**GOOD, "gain": 100}).encode(), "gain", "outside"),
        (json.dumps({**GOOD, "bit_depth": 12}).encode(), "bit_depth", "cam0 has 8"),
        (b" " * (MAX_REQUEST_BYTES + 1), None, "exceeds 4096"),
    ],
)
def test_bad_requests_get_an_error_naming_the_field(request_socket, request_bytes, field, match):
    socket, server = request_socket
    socket.send(request_bytes)
    (reply,) = socket.recv_multipart()
    error = json.loads(reply)
    assert error["field"] == field
    assert re.search(match, error["error"]), error["error"]
    assert server.frames_exposed == 0
    socket.send(json.dumps(GOOD).encode())  # and the server goes on
    assert len(socket.recv_multipart()) == 2


def test_a_multipart_request_is_refused(request_socket):
    socket, _ = request_socket
    socket.send_multipart([json.dumps(GOOD).encode(), b"extra"])
    (reply,) = socket.recv_multipart()
    assert "expected [b'', request]" in json.loads(reply)["error"]


def test_a_renderer_that_returns_the_wrong_image_is_reported(world):
    with CameraServer(world, lambda *_: np.zeros((8, 16), np.float32)) as server:
        context = zmq.Context()
        socket = context.socket(zmq.REQ)
        socket.setsockopt(zmq.LINGER, 0)
        socket.setsockopt(zmq.RCVTIMEO, 2000)
        socket.connect(server.url)
        try:
            socket.send(json.dumps(GOOD).encode())
            error = json.loads(socket.recv())
        finally:
            socket.close()
            context.term()
    assert error["field"] == "render"
    assert "float32 (8, 16)" in error["error"] and "uint8 (8, 16)" in error["error"]
