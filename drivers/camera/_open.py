"""The camera drivers, one per connection kind, registered for the ``camera`` role."""

from __future__ import annotations

import zmq

from drivers.camera._interface import Camera
from drivers.camera._opencv import OpenCvCamera
from drivers.camera._sim import SimCamera
from drivers.registry import register
from rig.clock import Clock
from rig.config import CameraSpec
from rig.devices import CAMERA_ROLE

__all__: list[str] = []  # importing this module registers the kinds


@register(CAMERA_ROLE, "sim")
def _open_sim(spec: CameraSpec, *, clock: Clock, context: zmq.Context | None = None) -> Camera:
    """``context`` lets several sim cameras share one ZeroMQ context."""
    return SimCamera(spec, clock=clock, context=context)


@register(CAMERA_ROLE, "opencv")
def _open_opencv(spec: CameraSpec, *, clock: Clock) -> Camera:
    return OpenCvCamera(spec, clock=clock)


@register(CAMERA_ROLE, "genicam")
def _open_genicam(spec: CameraSpec, *, clock: Clock) -> Camera:
    from drivers.camera._genicam import GenicamCamera  # optional extra: import on demand

    return GenicamCamera(spec, clock=clock)
