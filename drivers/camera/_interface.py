"""One camera interface for every driver: configure, trigger one frame, close.

A ``Frame`` carries the image and what it was taken with. Images are
``(height, width)`` for mono and ``(height, width, 3)`` RGB for colour cameras;
``uint8`` at bit depth 8 and ``uint16`` (values below ``2**bit_depth``) at 10,
12 and 16 bits. Drivers check every frame against the camera's spec and
re-capture a dropped (timed-out) or corrupt one with bounded retries before
raising a ``DeviceError`` naming the camera.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from drivers.retry import with_retries

__all__ = ["Camera", "CameraSettings", "Frame", "RetriedCapture"]


@dataclass(frozen=True)
class CameraSettings:
    """Exposure (s), gain (linear factor, 1 = unity) and bit depth of the next frames."""

    exposure_s: float
    gain: float
    bit_depth: int


@dataclass(frozen=True)
class Frame:
    """One captured image.

    Attributes
    ----------
    image : (H, W) or (H, W, 3) uint8 or uint16
    timestamp : float, s — start of the exposure: the simulator's world clock for
        the sim camera, the driver's injected clock at the trigger otherwise.
    exposure_s, gain : the settings the frame was taken with.
    sequence : the camera's frame counter; a gap means frames were dropped.
    camera_id : the rig config's camera id.
    """

    image: np.ndarray
    timestamp: float
    exposure_s: float
    gain: float
    sequence: int
    camera_id: str


class Camera(Protocol):
    """What the daemon needs from any camera (synchronous, like every driver)."""

    camera_id: str
    device: str
    settings: CameraSettings

    def configure(
        self,
        *,
        exposure_s: float | None = None,
        gain: float | None = None,
        bit_depth: int | None = None,
    ) -> CameraSettings:
        """Change the given settings (None: keep); returns the settings now in force."""

    def capture(self) -> Frame:
        """Trigger one exposure (software trigger) and return its checked frame."""

    def close(self) -> None:
        """Release the camera; idempotent."""


class RetriedCapture:
    """:meth:`capture` for a driver whose ``_capture_once`` fetches one frame: retried as
    its ``retry`` says on its ``clock``, the error naming its ``device``."""

    def capture(self) -> Frame:
        """One frame; a timeout, a dropped or a malformed frame is retried ``retry.retries``
        times."""
        return with_retries(
            self._capture_once,
            retry=self.retry,
            clock=self.clock,
            device=self.device,
            operation="capture",
        )

