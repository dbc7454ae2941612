"""GenICam cameras through harvesters and a GenTL producer (``.cti``): optional extra.

Install with ``pip install 'btfrig[genicam]'``. ``spec.connection.cti`` names
the producer (the camera vendor's, e.g. a GigE Vision or USB3 Vision
transport layer) and ``spec.connection.url`` the device's serial number.
Features follow the SFNC names: ``Width``/``Height`` are set to the spec,
``PixelFormat`` from channels and bit depth (Mono8/10/12/16, RGB8/RGB16),
``ExposureTime`` in µs, ``Gain`` in dB (20·log10 of the linear gain). A camera
with ``TriggerSoftware`` runs in trigger mode (FrameStart, source Software)
and each capture executes the trigger; a free-running producer without it is
triggered by starting acquisition for one frame and stopping again.
"""

from __future__ import annotations

import logging
import math

import numpy as np

from drivers.camera._checks import check_image, dtype_for, expected_shape, updated_settings
from drivers.camera._interface import CameraSettings, Frame, RetriedCapture
from drivers.errors import DeviceError, DeviceTimeout, ProtocolError
from rig.clock import Clock
from rig.config import CameraSpec

__all__ = ["GenicamCamera"]

log = logging.getLogger(__name__)

_PIXEL_FORMATS = {
    (1, 8): "Mono8",
    (1, 10): "Mono10",
    (1, 12): "Mono12",
    (1, 16): "Mono16",
    (3, 8): "RGB8",
    (3, 16): "RGB16",
}


class GenicamCamera(RetriedCapture):
    """One GenICam camera behind the camera interface."""

    def __init__(self, spec: CameraSpec, *, clock: Clock):
        try:
            from genicam.genapi import GenericException as FeatureException
            from genicam.gentl import GenericException, TimeoutException
            from harvesters.core import Harvester
        except ImportError as err:
            raise DeviceError(
                f"camera {spec.id}", "open", "GenICam needs: pip install 'btfrig[genicam]'"
            ) from err
        self._timeout_exception = TimeoutException
        self._feature_exception = FeatureException
        self.spec = spec
        self.camera_id = spec.id
        self.clock = clock
        self.retry = spec.connection.retry
        self.device = f"camera {spec.id} (genicam {spec.connection.url})"
        self._harvester = Harvester()
        try:
            self._harvester.add_file(spec.connection.cti, check_existence=True)
            self._harvester.update()
            self._acquirer = self._harvester.create({"serial_number": spec.connection.url})
        except (OSError, ValueError, GenericException) as err:
            found = [info.serial_number for info in self._harvester.device_info_list]
            self._harvester.reset()
            raise DeviceError(
                self.device,
                "open",
                f"no device with serial {spec.connection.url!r} through {spec.connection.cti} "
                f"(found serials {found}): {err}",
            ) from err
        self._nodes = self._acquirer.remote_device.node_map
        self.triggered = self._nodes.has_node("TriggerSoftware")
        self._sequence = 0
        self.settings = CameraSettings(exposure_s=0.01, gain=1.0, bit_depth=spec.bit_depth)
        try:
            self._set_node("Width", spec.width)
            self._set_node("Height", spec.height)
            self._set_node("PixelFormat", self._pixel_format(spec.bit_depth))
            if self.triggered:
                if self._nodes.has_node("TriggerSelector"):
                    self._set_node("TriggerSelector", "FrameStart")
                self._set_node("TriggerMode", "On")
                self._set_node("TriggerSource", "Software")
                self._acquirer.start()
        except DeviceError:
            self.close()
            raise

    @property
    def nodes(self):
        """The camera's GenApi node map, for vendor features this interface leaves out."""
        return self._nodes

    def _pixel_format(self, bit_depth: int) -> str:
        name = _PIXEL_FORMATS.get((self.spec.channels, bit_depth))
        valid = tuple(self._nodes.PixelFormat.symbolics)
        if name is None or name not in valid:
            raise DeviceError(
                self.device,
                "configure",
                f"no pixel format for {self.spec.channels} channel(s) at {bit_depth} bit "
                f"(wanted {name}); the camera offers {valid}",
            )
        return name

    def _set_node(self, name: str, value) -> None:
        if not self._nodes.has_node(name):
            raise DeviceError(self.device, "configure", f"the camera has no {name} feature")
        try:
            self._nodes.get_node(name).value = value
        except self._feature_exception as err:
            raise DeviceError(
                self.device, "configure", f"{name}={value!r} was refused: {err}"
            ) from err

    def configure(
        self,
        *,
        exposure_s: float | None = None,
        gain: float | None = None,
        bit_depth: int | None = None,
    ) -> CameraSettings:
        """Write the given settings to the camera's features (acquisition paused meanwhile)."""
        settings = updated_settings(
            self.device, self.settings, exposure_s=exposure_s, gain=gain, bit_depth=bit_depth
        )
        if self.triggered:
            self._acquirer.stop()
        try:
            if exposure_s is not None:
                self._set_node("ExposureTime", settings.exposure_s * 1e6)
            if gain is not None:
                self._set_node("Gain", 20.0 * math.log10(settings.gain))
            if bit_depth is not None:
                self._set_node("PixelFormat", self._pixel_format(settings.bit_depth))
        finally:
            if self.triggered:
                self._acquirer.start()
        self.settings = settings
        return settings

    def _capture_once(self) -> Frame:
        sequence = self._sequence
        self._sequence += 1
        timestamp = self.clock.now()
        if self.triggered:
            self._nodes.TriggerSoftware.execute()
        else:
            self._acquirer.start()
        try:
            image = self._fetch(sequence)
        finally:
            if not self.triggered:
                self._acquirer.stop()
        check_image(self.device, image, self.spec, self.settings.bit_depth)
        return Frame(
            image=image,
            timestamp=timestamp,
            exposure_s=self.settings.exposure_s,
            gain=self.settings.gain,
            sequence=sequence,
            camera_id=self.camera_id,
        )

    def _fetch(self, sequence: int) -> np.ndarray:
        timeout_s = self.retry.timeout_s + self.settings.exposure_s + self.spec.readout_s
        try:
            with self._acquirer.fetch(timeout=timeout_s) as buffer:
                component = buffer.payload.components[0]
                shape = expected_shape(self.spec)
                data = np.asarray(component.data)
                if (
                    data.size != math.prod(shape)
                    or (component.height, component.width) != shape[:2]
                ):
                    raise ProtocolError(
                        self.device,
                        "capture",
                        f"frame {sequence}: buffer of {data.size} values "
                        f"({component.width}×{component.height}), expected {shape}",
                    )
                return data.astype(dtype_for(self.settings.bit_depth)).reshape(shape)
        except self._timeout_exception as err:
            raise DeviceTimeout(
                self.device, "capture", f"frame {sequence} did not arrive in {timeout_s:.3f} s"
            ) from err

    def close(self) -> None:
        """Stop acquisition and release the device and the producer; idempotent."""
        if self._harvester is None:
            return
        try:
            self._acquirer.stop()
            self._acquirer.destroy()
        finally:
            self._harvester.reset()
            self._harvester = None
