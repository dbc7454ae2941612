"""The Wang rig's and the VirTex stage's device set: ``RigDevices`` with the roles they have.

A Wang rig drives turntable, light arc, lamp bank and (when the plan scans)
the laser unit; a VirTex stage only its lamp bank and camera, so its steps'
pose (0, 0) moves nothing.
"""

from __future__ import annotations

from orchestrator.daemon.devices import RigDevices
from orchestrator.daemon.kinds import DEVICE_SETS

__all__ = ["axes_devices"]


@DEVICE_SETS.register("devices", "wang")
@DEVICE_SETS.register("devices", "virtex")
def axes_devices(
    config, *, clock, lamps, cameras, turntable=None, light_arc=None, laser=None
) -> RigDevices:
    """The opened drivers of a rig of axes (absent roles: None)."""
    return RigDevices(
        config, clock=clock, turntable=turntable, arc=light_arc, lamps=lamps, laser=laser,
        cameras=cameras,
    )  # fmt: skip
