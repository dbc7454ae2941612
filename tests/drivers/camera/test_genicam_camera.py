"""The GenICam driver through harvesters against a real GenTL producer: the
simulated "Viky" producer (viky.cti) that the genicam wheel ships. Viky is
free-running with Width/Height/PixelFormat/AcquisitionFrameRate but no
ExposureTime, Gain or trigger features, so it also shows the driver's errors
for missing features."""

from pathlib import Path

import numpy as np
import pytest

harvesters = pytest.importorskip("harvesters", reason="the optional btfrig[genicam] extra")
genicam = pytest.importorskip("genicam", reason="the optional btfrig[genicam] extra")

from drivers import open_device  # noqa: E402
from drivers.errors import DeviceError, DeviceTimeout  # noqa: E402
from rig.clock import VirtualClock  # noqa: E402
from rig.config import CameraSpec  # noqa: E402
from rig.devices import GenicamConnection, Retry  # noqa: E402

CTI = sorted(Path(genicam.__file__).parent.glob("*.cti"))
pytestmark = pytest.mark.skipif(not CTI, reason="the genicam wheel ships no simulated .cti")
RETRY = Retry(timeout_s=1.0, retries=1, backoff_s=0.0)


def _spec(serial="0", *, channels=1, width=128, retry=RETRY):
    connection = GenicamConnection(url=serial, cti=str(CTI[0]), retry=retry)
    return CameraSpec(
        id="gc",
        theta_deg=0,
        width=width,
        height=100,
        channels=channels,
        readout_s=0.0,
        connection=connection,
    )


@pytest.fixture
def camera():
    camera = open_device("camera", _spec(), clock=VirtualClock())
    yield camera
    camera.close()


def test_frames_have_the_spec_shape_and_count_up(camera):
    assert not camera.triggered  # Viky has no TriggerSoftware: one-frame acquisitions
    frames = [camera.capture() for _ in range(3)]
    for i, frame in enumerate(frames):
        assert frame.image.shape == (100, 128) and frame.image.dtype == np.uint8
        assert frame.sequence == i and frame.camera_id == "gc"
    assert any(int(f.image.max()) > 0 for f in frames)


def test_a_missing_feature_is_named(camera):
    with pytest.raises(DeviceError, match=r"camera gc .*the camera has no ExposureTime feature"):
        camera.configure(exposure_s=0.01)
    with pytest.raises(DeviceError, match=r"no Gain feature"):
        camera.configure(gain=2.0)


def test_a_pixel_format_the_camera_lacks_lists_what_it_has():
    with pytest.raises(DeviceError, match=r"wanted RGB8\); the camera offers \('RGBa8', 'Mono8'\)"):
        open_device("camera", _spec(channels=3), clock=VirtualClock())


def test_a_size_out_of_range_is_refused():
    with pytest.raises(DeviceError, match=r"Width=64 was refused"):
        open_device("camera", _spec(width=64), clock=VirtualClock()).close()


def test_an_unknown_serial_lists_the_found_ones():
    with pytest.raises(
        DeviceError, match=r"no device with serial '42' .*found serials \['0', '1', '2'\]"
    ):
        open_device("camera", _spec("42"), clock=VirtualClock())


def test_frames_too_slow_for_the_timeout_give_a_timeout_after_retries():
    slow = _spec(retry=Retry(timeout_s=0.04, retries=1, backoff_s=0.0))
    camera = open_device("camera", slow, clock=VirtualClock())
    try:
        camera.nodes.AcquisitionFrameRate.value = 1.0  # one frame a second
        with pytest.raises(DeviceTimeout, match=r"did not arrive in 0.050 s .*gave up after 2"):
            camera.capture()
    finally:
        camera.close()
