"""Pick the camera driver a camera's connection names."""

from __future__ import annotations

import zmq

from drivers.camera._interface import Camera
from drivers.camera._opencv import OpenCvCamera
from drivers.camera._sim import SimCamera
from rig.clock import Clock
from rig.config import CameraSpec

__all__ = ["open_camera"]


def open_camera(spec: CameraSpec, *, clock: Clock, context: zmq.Context | None = None) -> Camera:
    """The driver for ``spec.connection.kind``: ``sim``, ``opencv`` or ``genicam``.

    ``context`` (sim cameras only) lets several cameras share one ZeroMQ context.
    """
    kind = spec.connection.kind
    if kind == "sim":
        return SimCamera(spec, clock=clock, context=context)
    if kind == "opencv":
        return OpenCvCamera(spec, clock=clock)
    from drivers.camera._genicam import GenicamCamera  # optional extra: import on demand

    return GenicamCamera(spec, clock=clock)
