"""Cameras through OpenCV: a UVC/V4L2 device by index, or an image sequence for replay.

``spec.connection.url`` is a device index (``"0"``) or a printf pattern
(``"frames/img_%04d.png"``, read with ``cv2.CAP_IMAGES``; 16-bit PNG/TIFF stay
16-bit). A live camera is free-running, so a capture grabs the next frame
after the call (the software trigger of a UVC camera); exposure goes to
``CAP_PROP_EXPOSURE`` in V4L2's unit of 100 µs with auto exposure off, gain
to ``CAP_PROP_GAIN`` (driver units ≈ linear). A replayed sequence delivers
what was recorded: its settings only label the frames, and the sequence
number is the file index. A frame that fails to arrive (live) or has the wrong
shape, dtype or range is re-captured with bounded retries.
"""

from __future__ import annotations

import logging

import cv2
import numpy as np

from drivers._lock import DeviceLock, serial_lock_key
from drivers.camera._checks import check_image, updated_settings
from drivers.camera._interface import CameraSettings, Frame, RetriedCapture
from drivers.errors import DeviceError, DeviceTimeout
from rig.clock import Clock
from rig.config import CameraSpec

__all__ = ["OpenCvCamera"]

log = logging.getLogger(__name__)

_V4L2_EXPOSURE_UNIT_S = 100e-6
_V4L2_MANUAL_EXPOSURE = 1


class OpenCvCamera(RetriedCapture):
    """A ``cv2.VideoCapture`` behind the camera interface."""

    def __init__(self, spec: CameraSpec, *, clock: Clock):
        self.spec = spec
        self.camera_id = spec.id
        self.clock = clock
        self.retry = spec.connection.retry
        url = spec.connection.url
        self.replay = not url.strip().isdigit()
        self.device = f"camera {spec.id} (opencv {url})"
        # a recorded sequence may be read by any number; a live camera has one owner
        self._lock = (
            None
            if self.replay
            else DeviceLock(f"v4l2 {serial_lock_key(f'/dev/video{int(url)}')}", device=self.device)
        )
        if self.replay:
            self._capture = cv2.VideoCapture(url, cv2.CAP_IMAGES)
        else:
            timeout_ms = round(self.retry.timeout_s * 1000)
            params = [cv2.CAP_PROP_OPEN_TIMEOUT_MSEC, timeout_ms]
            params += [cv2.CAP_PROP_READ_TIMEOUT_MSEC, timeout_ms]
            self._capture = cv2.VideoCapture(int(url), cv2.CAP_ANY, params)
        if not self._capture.isOpened():
            self.close()
            what = "no image matches the pattern" if self.replay else "no such video device"
            raise DeviceError(self.device, "open", f"{what} (connection.url={url!r})")
        self._frames = int(self._capture.get(cv2.CAP_PROP_FRAME_COUNT)) if self.replay else 0
        self._sequence = 0
        self.settings = CameraSettings(exposure_s=0.01, gain=1.0, bit_depth=spec.bit_depth)

    def configure(
        self,
        *,
        exposure_s: float | None = None,
        gain: float | None = None,
        bit_depth: int | None = None,
    ) -> CameraSettings:
        """Set exposure and gain on a live camera (labels only in replay); bit depth is fixed."""
        settings = updated_settings(
            self.device,
            self.settings,
            exposure_s=exposure_s,
            gain=gain,
            bit_depth=bit_depth,
            bit_depths=(self.spec.bit_depth,),
        )
        if not self.replay:
            self._set(cv2.CAP_PROP_AUTO_EXPOSURE, _V4L2_MANUAL_EXPOSURE, "auto exposure off")
            self._set(
                cv2.CAP_PROP_EXPOSURE,
                settings.exposure_s / _V4L2_EXPOSURE_UNIT_S,
                f"exposure_s={settings.exposure_s}",
            )
            self._set(cv2.CAP_PROP_GAIN, settings.gain, f"gain={settings.gain}")
        self.settings = settings
        return settings

    def _set(self, prop: int, value: float, what: str) -> None:
        if not self._capture.set(prop, value):
            raise DeviceError(self.device, "configure", f"the camera does not accept {what}")

    def _capture_once(self) -> Frame:
        timestamp = self.clock.now()
        ok, image = self._capture.read()
        sequence = self._sequence
        self._sequence += 1
        if not ok:
            if self.replay:
                raise DeviceError(
                    self.device,
                    "capture",
                    f"the image sequence ended (or frame {sequence} is unreadable) after "
                    f"{sequence} of {self._frames} frames",
                )
            raise DeviceTimeout(self.device, "capture", f"frame {sequence} did not arrive")
        if image.ndim == 3:
            image = cv2.cvtColor(image, cv2.COLOR_BGR2RGB)
        image = np.ascontiguousarray(image)
        check_image(self.device, image, self.spec, self.settings.bit_depth)
        return Frame(
            image=image,
            timestamp=timestamp,
            exposure_s=self.settings.exposure_s,
            gain=self.settings.gain,
            sequence=sequence,
            camera_id=self.camera_id,
        )

    def close(self) -> None:
        """Release the capture and the device; idempotent."""
        self._capture.release()
        if self._lock is not None:
            self._lock.release()
