"""The Wang rig's device set: ``RigDevices`` driving turntable, light arc, lamp bank and
(when the plan scans) the laser unit; a step's pose moves both axes at once."""

from __future__ import annotations

from orchestrator.daemon.devices import RigDevices
from orchestrator.daemon.kinds import DEVICE_SETS

__all__ = ["wang_devices"]


@DEVICE_SETS.register("devices", "wang")
def wang_devices(config, *, clock, lamps, cameras, turntable, light_arc, laser=None) -> RigDevices:
    """The opened drivers of a Wang rig (``laser``: None when the plan does not scan)."""
    return RigDevices(
        config, clock=clock, turntable=turntable, arc=light_arc, lamps=lamps, laser=laser,
        cameras=cameras,
    )  # fmt: skip
