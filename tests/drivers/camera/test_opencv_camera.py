"""The OpenCV driver replaying image sequences written with cv2.imwrite
(cv2.CAP_IMAGES): 8-bit colour, 16-bit mono, a corrupt frame re-captured, and
clear errors for a sequence that is all wrong or runs out."""

import cv2
import numpy as np
import pytest

from drivers import open_device
from drivers.camera import OpenCvCamera
from drivers.errors import DeviceError, ProtocolError
from rig.clock import VirtualClock
from rig.config import CameraSpec
from rig.devices import OpenCvConnection, Retry

RETRY = Retry(timeout_s=0.1, retries=2, backoff_s=0.0)


def _spec(url, **kwargs):
    connection = OpenCvConnection(url=url, retry=RETRY)
    return CameraSpec(id="replay", theta_deg=0, connection=connection, **kwargs)


def _write(folder, images):
    for i, image in enumerate(images):
        assert cv2.imwrite(str(folder / f"img_{i:04d}.png"), image)
    return str(folder / "img_%04d.png")


def test_colour_sequence_replays_in_order_as_rgb(tmp_path):
    rng = np.random.default_rng(1)
    frames = [rng.integers(0, 256, (48, 64, 3), dtype=np.uint8) for _ in range(3)]
    pattern = _write(tmp_path, [cv2.cvtColor(f, cv2.COLOR_RGB2BGR) for f in frames])
    clock = VirtualClock(10.0)
    camera = open_device("camera", _spec(pattern, width=64, height=48), clock=clock)
    try:
        assert isinstance(camera, OpenCvCamera) and camera.replay
        camera.configure(exposure_s=0.02, gain=2.0)
        for i, expected in enumerate(frames):
            frame = camera.capture()
            np.testing.assert_array_equal(frame.image, expected)
            assert (frame.sequence, frame.exposure_s, frame.gain) == (i, 0.02, 2.0)
            assert frame.timestamp == 10.0
    finally:
        camera.close()


def test_sixteen_bit_mono_png_stays_sixteen_bit(tmp_path):
    frames = [(np.arange(48 * 64, dtype=np.uint16).reshape(48, 64) * 21 + i) for i in range(2)]
    pattern = _write(tmp_path, frames)
    camera = OpenCvCamera(
        _spec(pattern, width=64, height=48, channels=1, bit_depth=16), clock=VirtualClock()
    )
    try:
        for expected in frames:
            frame = camera.capture()
            assert frame.image.dtype == np.uint16
            np.testing.assert_array_equal(frame.image, expected)
        assert int(frame.image.max()) > 255
    finally:
        camera.close()


def test_a_corrupt_frame_is_skipped_and_the_next_one_returned(tmp_path, caplog):
    good = np.full((24, 32), 7, np.uint8)
    pattern = _write(tmp_path, [good, np.zeros((20, 32), np.uint8), good + 1])
    camera = OpenCvCamera(_spec(pattern, width=32, height=24, channels=1), clock=VirtualClock())
    try:
        assert camera.capture().sequence == 0
        frame = camera.capture()
        assert frame.sequence == 2  # the gap shows that frame 1 was bad
        assert int(frame.image[0, 0]) == 8
        assert "shape (20, 32)" in caplog.text
    finally:
        camera.close()


def test_a_sequence_of_wrong_frames_fails_after_the_retries(tmp_path):
    pattern = _write(tmp_path, [np.zeros((24, 32, 3), np.uint8)] * 4)
    camera = OpenCvCamera(_spec(pattern, width=32, height=24, channels=1), clock=VirtualClock())
    try:
        with pytest.raises(
            ProtocolError, match=r"shape \(24, 32, 3\), the camera's spec says"
        ) as info:
            camera.capture()
        assert info.value.device == f"camera replay (opencv {pattern})"
        assert "gave up after 3 tries" in str(info.value)
    finally:
        camera.close()


def test_a_sequence_that_runs_out_says_so(tmp_path):
    pattern = _write(tmp_path, [np.zeros((24, 32), np.uint8)])
    camera = OpenCvCamera(_spec(pattern, width=32, height=24, channels=1), clock=VirtualClock())
    try:
        camera.capture()
        with pytest.raises(DeviceError, match=r"sequence ended .* after 1 of 1 frames"):
            camera.capture()
    finally:
        camera.close()


def test_a_pattern_with_no_images_cannot_be_opened(tmp_path):
    with pytest.raises(DeviceError, match=r"open failed: no image matches the pattern"):
        OpenCvCamera(_spec(str(tmp_path / "none_%04d.png")), clock=VirtualClock())


def test_replay_bit_depth_is_the_recordings(tmp_path):
    pattern = _write(tmp_path, [np.zeros((24, 32), np.uint8)])
    camera = OpenCvCamera(_spec(pattern, width=32, height=24, channels=1), clock=VirtualClock())
    try:
        with pytest.raises(DeviceError, match=r"bit_depth=12 is not supported; valid are \(8,\)"):
            camera.configure(bit_depth=12)
    finally:
        camera.close()


def test_a_live_device_index_that_does_not_exist_is_named():
    with pytest.raises(
        DeviceError, match=r"camera replay \(opencv 97\): open failed: no such video"
    ):
        OpenCvCamera(_spec("97"), clock=VirtualClock())
