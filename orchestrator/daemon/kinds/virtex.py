"""The VirTex stage's device set: ``RigDevices`` with its lamp bank and camera, no axes.

Its steps' pose (0, 0) moves nothing (``RigDevices.move`` refuses any other).
"""

from __future__ import annotations

from orchestrator.daemon.devices import RigDevices
from orchestrator.daemon.kinds import DEVICE_SETS

__all__ = ["fixed_devices"]


@DEVICE_SETS.register("devices", "virtex")
def fixed_devices(config, *, clock, lamps, cameras) -> RigDevices:
    """The opened lamp bank and cameras of a rig where nothing moves."""
    return RigDevices(
        config, clock=clock, turntable=None, arc=None, lamps=lamps, laser=None, cameras=cameras
    )
