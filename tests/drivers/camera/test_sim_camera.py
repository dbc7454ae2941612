"""The sim camera driver against the camera server over ZeroMQ TCP loopback.

The stand-in renderer paints the snapshot's turntable angle into the left half
and a bit mask of the lamps on into the right half, so a frame says exactly
what the motors and lamps had done when its exposure started."""

import time

import numpy as np
import pytest

from drivers import open_device
from drivers.camera import Frame
from drivers.errors import DeviceError, DeviceTimeout, ProtocolError
from rig.clock import VirtualClock
from rig.config import CameraArc, CameraSpec, RigConfig
from rig.devices import Retry, SimCameraConnection
from sim.peers.camera_server import CameraFaults, CameraServer
from sim.world import World

RETRY = Retry(timeout_s=0.2, retries=2, backoff_s=0.0)
CAMERAS = (
    CameraSpec(id="cam0", theta_deg=0, width=64, height=48, readout_s=0.05),
    CameraSpec(id="cam1", theta_deg=30, width=32, height=24, channels=1, bit_depth=12),
)


def paint_world(config):
    lamp_bits = {lamp.id: 1 << i for i, lamp in enumerate(config.light_arc.lamps)}

    def render(camera_id, snapshot, exposure_s):
        spec = config.camera(camera_id)
        shape = (spec.height, spec.width) if spec.channels == 1 else (spec.height, spec.width, 3)
        image = np.zeros(shape, np.uint8 if spec.bit_depth == 8 else np.uint16)
        image[:, : spec.width // 2] = round(snapshot.turntable_deg) % 256
        image[:, spec.width // 2 :] = sum(lamp_bits[lamp] for lamp in snapshot.lamps_on)
        return image

    return render


@pytest.fixture
def world():
    return World(RigConfig(camera_arc=CameraArc(cameras=CAMERAS)), VirtualClock())


@pytest.fixture
def server(world):
    with CameraServer(world, paint_world(world.config)) as server:
        yield server


def _camera(world, server, camera_id="cam0"):
    spec = world.config.camera(camera_id)
    connection = SimCameraConnection(url=server.url, retry=RETRY)
    return open_device(
        "camera", spec.model_copy(update={"connection": connection}), clock=world.clock
    )


@pytest.fixture
def camera(world, server):
    camera = _camera(world, server)
    yield camera
    camera.close()


def _left_right(frame: Frame) -> tuple[int, int]:
    w = frame.image.shape[1]
    return int(frame.image[0, 0].max()), int(frame.image[0, w - 1].max())


def test_the_camera_sees_what_the_motors_and_lamps_did(world, camera):
    world.move("turntable", 90.0)
    world.set_lamp("lamp0", True)
    world.set_lamp("lamp3", True)
    world.clock.sleep(10.0)  # the move is over
    frame = camera.capture()
    assert frame.image.shape == (48, 64, 3) and frame.image.dtype == np.uint8
    assert _left_right(frame) == (90, 0b1001)
    assert frame.camera_id == "cam0"


def test_a_frame_during_a_move_shows_the_angle_at_the_start_of_the_exposure(world, camera):
    world.move("turntable", 180.0)
    world.clock.sleep(2.0)
    expected = round(world.position("turntable"))
    assert 0 < expected < 180
    assert _left_right(camera.capture())[0] == expected


def test_a_dead_lamp_stays_dark(world, camera):
    world.dead_lamps.add("lamp1")
    world.set_lamp("lamp1", True)
    world.set_lamp("lamp2", True)
    assert _left_right(camera.capture())[1] == 0b100


def test_exposure_and_readout_take_world_time(world, camera):
    camera.configure(exposure_s=0.25)
    t0 = world.clock.now()
    first = camera.capture()
    second = camera.capture()
    assert first.timestamp == pytest.approx(t0)
    assert second.timestamp == pytest.approx(t0 + 0.25 + 0.05)
    assert world.clock.now() == pytest.approx(t0 + 2 * 0.30)
    assert (first.sequence, second.sequence) == (0, 1)
    assert first.exposure_s == 0.25


def test_gain_is_applied_and_saturates(world, camera):
    world.move("turntable", 100.0)
    world.clock.sleep(10.0)
    camera.configure(gain=2.0)
    frame = camera.capture()
    assert _left_right(frame)[0] == 200
    assert frame.gain == 2.0
    camera.configure(gain=3.0)
    assert _left_right(camera.capture())[0] == 255


def test_twelve_bit_mono_camera(world, server):
    camera = _camera(world, server, "cam1")
    try:
        world.move("turntable", 45.0)
        world.clock.sleep(10.0)
        frame = camera.capture()
        assert frame.image.shape == (24, 32) and frame.image.dtype == np.uint16
        assert int(frame.image[0, 0]) == 45
    finally:
        camera.close()


@pytest.mark.parametrize("fault", ["dropped_frames", "corrupt_frames", "wrong_size_frames"])
def test_one_bad_frame_is_recaptured(world, server, camera, fault):
    setattr(server.faults, fault, 1)
    frame = camera.capture()
    assert frame.sequence == 1  # frame 0 was the bad one
    assert getattr(server.faults, fault) == 0
    assert server.frames_exposed == 2


@pytest.mark.parametrize(
    ("fault", "error", "match"),
    [
        ("dropped_frames", DeviceTimeout, r"no frame within .*dropped"),
        ("corrupt_frames", ProtocolError, r"is corrupt: crc32"),
        ("wrong_size_frames", ProtocolError, r"shape|\(47, 64, 3\)"),
    ],
)
def test_bad_frames_every_time_give_a_clear_error(world, server, camera, fault, error, match):
    setattr(server.faults, fault, 100)
    with pytest.raises(error, match=match) as info:
        camera.capture()
    assert info.value.device == f"camera cam0 (sim {server.url})"
    assert "gave up after 3 tries" in str(info.value)
    assert server.frames_exposed == 3


def test_a_late_frame_is_not_mistaken_for_the_next_one(world, server, camera):
    # A dropped reply, then the retry's frame: request ids keep them apart, and
    # the next capture gets its own, newer frame.
    server.faults.dropped_frames = 1
    first = camera.capture()
    second = camera.capture()
    assert second.sequence == first.sequence + 1


def test_faults_for_another_camera_leave_this_one_alone(world, server, camera):
    server.faults = CameraFaults(dropped_frames=5, camera_id="cam1")
    assert camera.capture().sequence == 0
    assert server.faults.dropped_frames == 5


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        (dict(exposure_s=0.0), r"exposure_s=0.0 is outside \(0, 60.0\]"),
        (dict(exposure_s=120.0), r"exposure_s=120.0"),
        (dict(gain=-1.0), r"gain=-1.0"),
        (dict(bit_depth=16), r"bit_depth=16 is not supported; valid are \(8,\)"),
    ],
)
def test_bad_settings_are_refused_naming_the_field(camera, kwargs, match):
    with pytest.raises(DeviceError, match=match):
        camera.configure(**kwargs)


def test_a_camera_the_server_does_not_know_is_refused_at_once(world, server):
    spec = CameraSpec(id="ghost", theta_deg=10, width=8, height=8)
    connection = SimCameraConnection(url=server.url, retry=RETRY)
    camera = open_device(
        "camera", spec.model_copy(update={"connection": connection}), clock=world.clock
    )
    try:
        with pytest.raises(DeviceError, match=r"refused: camera_id 'ghost' is unknown.*camera_id"):
            camera.capture()
    finally:
        camera.close()
    assert server.frames_exposed == 0


def test_no_server_times_out(world):
    spec = CAMERAS[0].model_copy(
        update={"connection": SimCameraConnection(url="tcp://127.0.0.1:9", retry=RETRY)}
    )
    camera = open_device("camera", spec, clock=world.clock)
    try:
        with pytest.raises(DeviceTimeout, match=r"camera cam0 .*gave up after 3 tries"):
            camera.capture()
    finally:
        camera.close()


def test_a_render_slower_than_the_timeout_is_waited_for_not_recaptured(world):
    # The simulator's render takes wall time the camera model does not have: the
    # server says it is busy, and the one frame it renders is the one delivered.
    paint = paint_world(world.config)

    def slow(camera_id, snapshot, exposure_s):
        time.sleep(4 * RETRY.timeout_s)
        return paint(camera_id, snapshot, exposure_s)

    with CameraServer(world, slow) as server:
        camera = _camera(world, server)
        try:
            frame = camera.capture()
        finally:
            camera.close()
    assert frame.sequence == 0
    assert server.frames_exposed == 1
