"""The device facade: the one object a session drives.

``RigDevices`` composes the drivers of one rig (turntable, light arc, lamp
bank, laser unit, cameras; a VirTex stage has only its lamps and camera)
behind the step vocabulary of a session: move both axes in parallel and wait
until they have settled, switch a lamp or the laser, trigger every camera of a
step together and read them, sweep the laser sheet while the cameras record.
Drivers are synchronous and retry on their own; a ``DeviceError`` reaching the
facade has survived those retries.

``build_devices(config, clock=..., scale=...)`` opens, through
``drivers.open_device``, the driver each device section's ``kind`` names, and
composes them into the rig kind's device set (``orchestrator.daemon.kinds``:
``RigDevices``, or the Bonn lab's ``BonnDevices``). Tests
build ``RigDevices`` from in-process soft devices with the same interfaces
(``drivers.interfaces``).
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import replace
from typing import Protocol

from drivers import DeviceError, open_device
from drivers.camera import Camera, Frame
from drivers.interfaces import Axis, LampBank, LaserUnit
from orchestrator.daemon.kinds import DEVICE_SETS
from orchestrator.daemon.scan import Captured, Scan, sweep_scan
from rig.clock import Clock
from rig.config import RigConfig
from rig.steps import AxesPose

__all__ = [
    "Captured",
    "DeviceSet",
    "RigDevices",
    "Scan",
    "ThreadedCamera",
    "build_devices",
]

log = logging.getLogger(__name__)


class ThreadedCamera:
    """The daemon's handle on a driver camera (``drivers.camera.Camera``): ``trigger``
    starts its blocking ``capture`` and returns at once, ``read`` waits for the frame.

    The capture runs on the handle's own thread so that several cameras expose
    together. With ``scale`` < 1 each frame is binned in software (area
    averaging, ``cv2.INTER_AREA``) to the plan's resolution.
    """

    def __init__(self, camera: Camera, name: str, *, scale: float = 1.0):
        self._camera = camera
        self._scale = scale
        self._pool = ThreadPoolExecutor(1, thread_name_prefix=f"camera-{name}")
        self._pending: Future | None = None

    def trigger(self, exposure_s: float) -> None:
        """Start an exposure of ``exposure_s``; returns at once."""
        self._pending = self._pool.submit(self._expose, exposure_s)

    def _expose(self, exposure_s: float) -> Frame:
        self._camera.configure(exposure_s=exposure_s)
        frame = self._camera.capture()
        if self._scale == 1.0:
            return frame
        import cv2

        h, w = frame.image.shape[:2]
        size = (max(1, round(w * self._scale)), max(1, round(h * self._scale)))
        return replace(frame, image=cv2.resize(frame.image, size, interpolation=cv2.INTER_AREA))

    def read(self) -> Frame:
        """Wait for the triggered frame and return it (the driver's ``DeviceError`` if
        none came after its retries)."""
        pending, self._pending = self._pending, None
        if pending is None:
            raise RuntimeError("read() without a trigger()")
        return pending.result()

    def close(self) -> None:
        self._pool.shutdown(wait=True)
        self._camera.close()


class DeviceSet(Protocol):
    """What a session needs from the rig (``RigDevices``, or replay devices)."""

    def home(self, *, laser: bool) -> None: ...
    def place(self, pose) -> dict[str, float]:
        """Move to a step's pose (its rig kind's) and settle; the actuators' read-back."""
    def lamp(self, lamp_id: str, on: bool) -> None: ...
    def laser(self, mount: int, on: bool) -> None: ...
    def capture(
        self, cameras: Sequence[str], exposures_s: Sequence[float]
    ) -> dict[str, list[Captured]]: ...
    def scan(
        self,
        cameras: Sequence[str],
        *,
        tilt_deg: tuple[float, float],
        frames: int,
        exposure_s: float,
    ) -> Scan: ...
    def forget_position(self) -> None: ...
    def all_off(self) -> None: ...
    def telemetry(self) -> dict: ...
    def close(self) -> None: ...


class RigDevices:
    """The drivers of one rig behind the session's step vocabulary."""

    def __init__(
        self,
        config: RigConfig,
        *,
        clock: Clock,
        turntable: Axis | None,
        arc: Axis | None,
        lamps: LampBank,
        laser: LaserUnit | None,
        cameras: Mapping[str, ThreadedCamera],
    ):
        self.config = config
        self.clock = clock
        self.turntable = turntable
        self.arc = arc
        self.lamps = lamps
        self.laser_unit = laser
        self.cameras = dict(cameras)
        self._position: dict[str, float | None] = {"turntable_deg": None, "arc_deg": None}
        self._tilt_deg = 0.0

    @property
    def _axes(self) -> list[Axis]:
        return [axis for axis in (self.turntable, self.arc) if axis is not None]

    def home(self, *, laser: bool) -> None:
        """Lamps off, home the turntable and the arc; check the laser unit, tilt it to 0."""
        self.lamps.switch(frozenset())
        for axis in self._axes:
            axis.home()
        self._position = {"turntable_deg": 0.0, "arc_deg": None}
        if laser:
            unit = self._laser_unit()
            unit.check_battery()
            unit.set_laser(False)
            unit.tilt.home()
            self._tilt_deg = 0.0

    def move(self, *, turntable_deg: float, arc_deg: float) -> dict[str, float]:
        """Move both axes at once, wait until both stop, then wait the longer settle time.

        A rig without axes (a VirTex stage) stays where it is, which only the
        pose (0, 0) asks for; it reports no actuator positions.
        """
        if not self._axes:
            if turntable_deg != 0.0 or arc_deg != 0.0:
                raise DeviceError(
                    "rig", "move", f"this {self.config.kind} rig has no turntable or arc to "
                    f"move to ({turntable_deg}°, {arc_deg}°)",
                )  # fmt: skip
            return {}
        moving_tt = self._position["turntable_deg"] != turntable_deg
        moving_arc = self._position["arc_deg"] != arc_deg
        if moving_tt:
            self.turntable.move_to(turntable_deg)
        if moving_arc:
            self.arc.move_to(arc_deg)
        # Forget the position first: a failed wait leaves it unknown.
        self._position = {"turntable_deg": None, "arc_deg": None}
        tt = self.turntable.wait_until_settled() if moving_tt else turntable_deg
        arc = self.arc.wait_until_settled() if moving_arc else arc_deg
        settle = max(
            self.turntable.settle_s if moving_tt else 0.0,
            self.arc.settle_s if moving_arc else 0.0,
        )
        self.clock.sleep(settle)
        self._position = {"turntable_deg": turntable_deg, "arc_deg": arc_deg}
        return {"turntable_deg": float(tt), "arc_deg": float(arc)}

    def place(self, pose: AxesPose) -> dict[str, float]:
        """:meth:`move` to a step's pose."""
        return self.move(turntable_deg=pose.turntable_deg, arc_deg=pose.arc_deg)

    def forget_position(self) -> None:
        """Forget where the axes were sent: the next ``move`` sends both again (a
        frame found them elsewhere)."""
        self._position = {"turntable_deg": None, "arc_deg": None}

    def lamp(self, lamp_id: str, on: bool) -> None:
        """Light exactly ``lamp_id`` (the bank waits for its warm-up), or switch all off."""
        self.lamps.switch(frozenset({lamp_id}) if on else frozenset())

    def laser(self, mount: int, on: bool) -> None:
        """Light the laser diode of mount ``mount`` alone, or switch the diodes off."""
        mounts = len(self.config.laser.mount_theta_deg)
        if not 0 <= mount < mounts:
            raise DeviceError(
                "laser brick", f"laser {'on' if on else 'off'}",
                f"mount {mount} does not exist; laser.mount_theta_deg has {mounts}",
            )  # fmt: skip
        self._laser_unit().set_laser(on, mount=mount)

    def capture(
        self, cameras: Sequence[str], exposures_s: Sequence[float]
    ) -> dict[str, list[Captured]]:
        """For each exposure, trigger all ``cameras`` together, then read each."""
        frames: dict[str, list[Captured]] = {c: [] for c in cameras}
        for sub, exposure in enumerate(exposures_s):
            self._shoot(cameras, exposure, sub, frames)
        return frames

    def scan(
        self,
        cameras: Sequence[str],
        *,
        tilt_deg: tuple[float, float],
        frames: int,
        exposure_s: float,
    ) -> Scan:
        """Sweep the sheet from ``tilt_deg[0]`` to ``[1]`` recording ``frames`` frames.

        The frames are planned at ``rig.frame_check.scan_tilts_deg`` (spread over
        the sweep, never closer than the sheet moves in a laser frame period). Each
        is triggered when the tilt motor's tacho count says the sheet has reached its
        tilt, and checked against it: the tilt read back before the trigger and after
        the frame came back must both lie within ``tilt_tolerance_deg`` of it, and the
        camera's timestamp must be later than the frame before's. A frame that fails
        (the sheet ran ahead of the camera) is taken again after the sweep with the
        sheet held at its tilt, and flagged. The sheet returns to the start afterwards.
        """
        start = tilt_deg[0]
        if self._tilt_deg != start:
            self._tilt_deg = self._tilt_to(start)
        scan = sweep_scan(
            self._laser_unit().tilt, self.config, self.clock, cameras,
            tilt_deg=tilt_deg, frames=frames, exposure_s=exposure_s,
            shoot=self._shoot, hold=self._tilt_to,
        )  # fmt: skip
        self._tilt_deg = self._tilt_to(start)
        return scan

    def _tilt_to(self, deg: float) -> float:
        tilt = self._laser_unit().tilt
        tilt.move_to(deg)
        return tilt.wait_until_settled()

    def _shoot(self, cameras, exposure_s, sub, frames) -> None:
        with self.clock.parallel():  # the cameras expose at once: time passes once
            for camera in cameras:
                self._camera(camera).trigger(exposure_s)
            for camera in cameras:
                frame = self._camera(camera).read()
                frames[camera].append(
                    Captured(frame.image, sub, float(frame.exposure_s), float(frame.timestamp))
                )

    def _off_actions(self) -> list[Callable[[], object]]:
        """What switching the rig off does, one device each: lamps and laser off, axes stopped."""
        actions = [lambda: self.lamps.switch(frozenset()), *(a.stop for a in self._axes)]
        if self.laser_unit is not None:
            actions += [lambda: self.laser_unit.set_laser(False), self.laser_unit.tilt.stop]
        return actions

    def all_off(self) -> None:
        """Every one of :meth:`_off_actions` tried, the first error raised."""
        errors = []
        for action in self._off_actions():
            try:
                action()
            except DeviceError as err:
                log.warning("switching off: %s", err)
                errors.append(err)
        if errors:
            raise errors[0]

    def telemetry(self) -> dict:
        """Positions and lamps as the devices report them (for the events stream)."""
        axes = {"turntable_deg": self.turntable, "arc_deg": self.arc}
        positions = {name: float(a.position()) for name, a in axes.items() if a is not None}
        return {**positions, "lamps_on": sorted(self.lamps.lamps_on())}

    def close(self) -> None:
        """Close every device, even if some fail; idempotent."""
        devices = [*self._axes, self.lamps, *self.cameras.values()]
        if self.laser_unit is not None:
            devices.append(self.laser_unit)
        for device in devices:
            try:
                device.close()
            except DeviceError as err:
                log.warning("closing: %s", err)

    def _camera(self, camera: str) -> ThreadedCamera:
        try:
            return self.cameras[camera]
        except KeyError:
            raise DeviceError(
                camera, "capture", f"no such camera; this rig has {sorted(self.cameras)}"
            ) from None

    def _laser_unit(self) -> LaserUnit:
        if self.laser_unit is None:
            raise DeviceError("laser brick", "scan", "this rig was opened without a laser unit")
        return self.laser_unit


def build_devices(
    config: RigConfig, *, clock: Clock, scale: float = 1.0, laser: bool = True
) -> DeviceSet:
    """Open the driver of every device ``config`` names (the simulator's peers answer
    the same way); what opened is closed again if a later one fails.

    ``scale`` is the plan's resolution factor (binned in software); with
    ``laser=False`` the laser unit is not opened (plans without scans). Only
    the roles of the config's kind open (``RigConfig.device_roles``).
    """
    opened: list = []

    def opening(role: str, section, **options):
        device = open_device(role, section, clock=clock, **options)
        opened.append(device)
        return device

    compose = DEVICE_SETS.lookup("devices", config.kind)
    if compose is None:
        raise DeviceError(
            "rig", "open", f"no device set serves a {config.kind!r} rig; "
            f"served are {DEVICE_SETS.served('devices')}",
        )  # fmt: skip
    try:
        actuators = {}
        for role in config.device_roles:
            if role == "lamp_bank":
                lamp_ids = [lamp.id for lamp in config.lamps]
                lamps = opening(role, config.lamp_bank, lamp_ids=lamp_ids)
            elif laser or role != "laser":
                actuators[role] = opening(role, config.device_section(role))
        cameras = {}
        for spec in config.camera_arc.cameras:
            cameras[spec.id] = ThreadedCamera(opening("camera", spec), spec.id, scale=scale)
    except BaseException:
        for device in reversed(opened):
            device.close()
        raise
    return compose(config, clock=clock, lamps=lamps, cameras=cameras, **actuators)
