"""The Bonn lab's device set: the arm turns the plate, the rail moves the camera.

``BonnDevices`` is a ``RigDevices`` without turntable and arc, with the arm
(a ``drivers.interfaces.Positioner``) and the rail (an ``Axis``); a step's pose
(``rig.bonn_plan.ArmRailPose``) places both (:meth:`BonnDevices.place`) instead
of moving the two Wang axes. What it records as actuator state: the rail
position and the tool pose the arm reports.

A protective stop of the arm fails the step (``DeviceFault`` naming the arm: the
session pauses); the next :meth:`~BonnDevices.place` — the step retried when
the operator resumes — unlocks the stop first, then sends the move again.
"""

from __future__ import annotations

import logging
from collections.abc import Callable

import numpy as np

from drivers import DeviceError
from drivers.errors import DeviceFault
from drivers.interfaces import Axis, Positioner
from orchestrator.daemon.devices import RigDevices
from orchestrator.daemon.kinds import DEVICE_SETS
from rig.bonn import plate_rotation, plate_tool_pose
from rig.bonn_plan import ArmRailPose

__all__ = ["BonnDevices"]

log = logging.getLogger(__name__)


class BonnDevices(RigDevices):
    """``RigDevices`` of a Bonn lab: lamp bank, camera, and the arm and rail."""

    def __init__(self, config, *, arm: Positioner, rail: Axis, **devices):
        super().__init__(config, turntable=None, arc=None, laser=None, **devices)
        self.arm = arm
        self.rail = rail
        self._stopped = False  # the arm ended its last move in a protective stop

    def home(self, *, laser: bool) -> None:
        """Lamps off; power the arm and release its brakes; home the rail."""
        super().home(laser=laser)
        self.arm.home()
        self.rail.home()

    def place(self, pose: ArmRailPose) -> dict[str, float]:
        """Turn the plate to where the arm's ``pose.joints_deg`` hold it and move the rail to
        ``pose.rail_deg``, at once; wait until both stop, then the longer settle time.

        Returns the rail position and the arm's tool pose as read back (mm, deg).
        """
        if self._stopped:  # resumed by the operator: clear the stop, then move again
            self.arm.unlock_protective_stop()
            self._stopped = False
        rotation = plate_rotation(self.config, np.radians(pose.joints_deg))
        self.arm.move_to(plate_tool_pose(self.config, rotation))
        self.rail.move_to(pose.rail_deg)
        try:
            tool = self.arm.wait_until_settled()
        except DeviceFault:
            self._stopped = True
            raise
        rail = self.rail.wait_until_settled()
        self.clock.sleep(max(self.arm.settle_s, self.rail.settle_s))
        x, y, z = (1000.0 * v for v in tool.position_m)
        rx, ry, rz = np.degrees(tool.rotvec)
        return {
            "rail_deg": float(rail), "tool_x_mm": x, "tool_y_mm": y, "tool_z_mm": z,
            "tool_rx_deg": float(rx), "tool_ry_deg": float(ry), "tool_rz_deg": float(rz),
        }  # fmt: skip

    def _off_actions(self) -> list[Callable[[], object]]:
        """The rig's, then the arm and the rail stopped."""
        return [*super()._off_actions(), self.arm.stop, self.rail.stop]

    def telemetry(self) -> dict:
        return {**super().telemetry(), "rail_deg": float(self.rail.position())}

    def close(self) -> None:
        super().close()
        for device in (self.arm, self.rail):
            try:
                device.close()
            except DeviceError as err:
                log.warning("closing: %s", err)


DEVICE_SETS.register("devices", "bonn")(BonnDevices)
