"""The LEGO laser unit: an NXT motor tilts the laser sheet, another output powers the diode.

The tilt is an ``Axis`` (``NxtTilt``, the ``tilt`` attribute). The diode hangs
on output ``unit.laser_port`` driven at constant power (``unit.laser_power``
%, motor on, unregulated): an NXT output is the only place with switchable
4.3–9 V on the brick, and unlike a powered sensor type (SETINPUTMODE) it can
be read back with GETOUTPUTSTATE. A second mount's diode is on the third
output (``NxtLaserUnit.diode_ports``); the same motor tilts both.
"""

from __future__ import annotations

import logging

from drivers.errors import DeviceError, DeviceFault
from drivers.nxt._brick import NxtBrick
from drivers.nxt._telegram import MOTOR_PORTS, OutputMode, RegulationMode, RunState
from drivers.nxt._tilt import NxtTilt
from drivers.registry import register
from rig.clock import Clock
from rig.config import Laser
from rig.devices import NxtLaserUnit

__all__ = ["NxtLaser"]

log = logging.getLogger(__name__)


class NxtLaser:
    """Switch the diode and tilt the sheet of one LEGO laser unit (synchronous).

    Satisfies ``drivers.interfaces.LaserUnit``.

    Parameters
    ----------
    brick : an open ``NxtBrick``; closed by ``close``.
    unit : the laser's device section (ports, gear ratio, power, limits).
    mounts : how many mounts (diodes) the unit lights, one at a time.
    tilt_limit_deg, tilt_speed_deg_s : the tilt's range (±) and speed (deg, deg/s).
    clock : injected time for polling and stall detection.
    poll_s : interval between polls while waiting for a tilt.
    """

    def __init__(
        self,
        brick: NxtBrick,
        unit: NxtLaserUnit,
        *,
        mounts: int = 1,
        tilt_limit_deg: float,
        tilt_speed_deg_s: float,
        clock: Clock,
        poll_s: float = 0.05,
    ):
        self.brick = brick
        self.unit = unit
        self.device = brick.device
        self._diodes = [MOTOR_PORTS[port] for port in unit.diode_ports(mounts)]
        self.tilt = NxtTilt(
            brick,
            unit,
            limit_deg=tilt_limit_deg,
            speed_deg_s=tilt_speed_deg_s,
            clock=clock,
            poll_s=poll_s,
        )

    def check_battery(self) -> int:
        """The battery voltage (mV); ``DeviceFault`` below ``unit.min_battery_mv``."""
        mv = self.brick.battery_level_mv()
        if mv < self.unit.min_battery_mv:
            raise DeviceFault(
                self.device,
                "battery check",
                f"battery at {mv} mV, below the minimum {self.unit.min_battery_mv} mV "
                "(motor speed and laser power would drift): charge or replace the cells",
            )
        return mv

    def set_laser(self, on: bool, *, mount: int = 0) -> None:
        """Light mount ``mount``'s diode alone (its output at constant power), or
        switch every diode off (float)."""
        if not 0 <= mount < len(self._diodes):
            raise DeviceError(
                self.device, f"laser {'on' if on else 'off'}",
                f"mount {mount} has no diode; this unit lights mounts 0..{len(self._diodes) - 1}",
            )  # fmt: skip
        for index, port in enumerate(self._diodes):
            if index != mount:
                self._switch(port, False)
        self._switch(self._diodes[mount], on)

    def _switch(self, port: int, on: bool) -> None:
        self.brick.set_output_state(
            port,
            power=self.unit.laser_power if on else 0,
            mode=OutputMode.MOTORON if on else OutputMode.COAST,
            regulation=RegulationMode.IDLE,
            run_state=RunState.RUNNING if on else RunState.IDLE,
        )

    def laser_is_on(self, *, mount: int = 0) -> bool:
        state = self.brick.get_output_state(self._diodes[mount])
        return bool(state.mode & OutputMode.MOTORON) and state.power != 0

    def close(self) -> None:
        """Switch the diode off (best effort) and close the link."""
        try:
            self.set_laser(False)
        except DeviceError as err:
            log.warning("%s: could not switch the laser off before closing: %s", self.device, err)
        finally:
            self.brick.close()


@register("laser", "nxt")
def open_laser(section: Laser, *, clock: Clock, usb_backend=None) -> NxtLaser:
    """The laser unit of a rig config, on the brick ``section.device`` names (USB or
    serial); ``usb_backend``: pyusb's (the simulator's fake brick passes its own)."""
    brick = NxtBrick.open(
        section.device, clock=clock, device="laser brick", usb_backend=usb_backend
    )
    return NxtLaser(
        brick,
        section.device,
        mounts=len(section.mount_theta_deg),
        tilt_limit_deg=section.tilt_limit_deg,
        tilt_speed_deg_s=section.sweep_speed_deg_s,
        clock=clock,
    )
