"""Soft devices: in-process turntable, arc, lamps, laser and cameras on one clock.

They implement the driver interfaces the facade uses (``drivers.interfaces``
and ``drivers.camera.Camera``), model motion and exposure time on the injected
clock (parallel axes overlap: each wait sleeps only up to its own end), make
deterministic frames from the rig's state, record any exposure taken while an
axis moved, and inject faults on request (stall, timeout, dropped frame, a dark
lamp; a stray lamp lit or the turntable bumped during an exposure, a stale
frame). Used by the daemon tests, in process and in ``soft_daemon.py``.
"""

from __future__ import annotations

import threading
import time
import zlib
from collections import Counter
from dataclasses import dataclass, field, replace

import numpy as np

from drivers.camera import CameraSettings, Frame
from drivers.errors import DeviceFault, DeviceTimeout, MotionStalled
from orchestrator.daemon import RigDevices, ThreadedCamera, frame_formats
from rig.archive import FrameFormat
from rig.clock import Clock
from rig.config import Axis, RigConfig


@dataclass
class Faults:
    """Faults to inject: ``arm("turntable.wait", "stall", times=1)``."""

    armed: dict[str, list[str]] = field(default_factory=dict)
    fired: Counter = field(default_factory=Counter)
    lock: threading.Lock = field(default_factory=threading.Lock)

    def arm(self, where: str, kind: str, *, times: int = 1) -> None:
        with self.lock:
            self.armed.setdefault(where, []).extend([kind] * times)

    def take(self, where: str) -> str | None:
        with self.lock:
            kinds = self.armed.get(where)
            if not kinds:
                return None
            self.fired[where] += 1
            return kinds.pop(0)


@dataclass
class SoftRig:
    """The shared state of the soft devices."""

    config: RigConfig
    clock: Clock
    faults: Faults = field(default_factory=Faults)
    real_delay_s: float = 0.0  # real seconds per camera read (to kill a daemon mid-session)
    turntable_deg: float = 0.0
    arc_deg: float = 0.0
    moving_until: dict = field(default_factory=lambda: {"turntable": 0.0, "arc": 0.0})
    lamps_on: frozenset = frozenset()
    lamp_switches: list = field(default_factory=list)  # every set the bank was told to light
    laser_on: bool = False
    violations: list = field(default_factory=list)
    captures: list = field(default_factory=list)
    opened: int = 0
    closed: int = 0

    def moving(self) -> list[str]:
        now = self.clock.now()
        return [a for a, t in self.moving_until.items() if t > now + 1e-12]


class SoftAxis:
    def __init__(self, rig: SoftRig, name: str, axis: Axis):
        self.rig, self.name, self.axis = rig, name, axis
        self.settle_s = axis.settle_s
        self._target = None

    def home(self) -> None:
        self._check("home")
        self.rig.clock.sleep(float(self.axis.move_time_s(getattr(self.rig, self._attr))))
        setattr(self.rig, self._attr, 0.0)

    @property
    def _attr(self) -> str:
        return f"{self.name}_deg"

    def move_to(self, deg: float) -> None:
        self._check("move")
        start = getattr(self.rig, self._attr)
        self.rig.moving_until[self.name] = self.rig.clock.now() + float(
            self.axis.move_time_s(deg - start)
        )
        self._target = deg
        setattr(self.rig, self._attr, float("nan"))  # unknown while moving

    def position(self) -> float:
        value = getattr(self.rig, self._attr)
        return self._target if np.isnan(value) else value

    def wait_until_settled(self, timeout_s: float | None = None) -> float:
        clock = self.rig.clock
        clock.sleep(max(0.0, self.rig.moving_until[self.name] - clock.now()))
        kind = self.rig.faults.take(f"{self.name}.wait")
        if kind == "stall":
            raise MotionStalled(self.name, "move_to", f"stopped short of {self._target}°")
        if kind == "timeout":
            raise DeviceTimeout(self.name, "move_to", "no reply (gave up after 4 tries)")
        setattr(self.rig, self._attr, self._target)
        return self._target

    def stop(self) -> None:
        pass

    def close(self) -> None:
        self.rig.closed += 1

    def _check(self, operation: str) -> None:
        if self.rig.faults.take(f"{self.name}.{operation}") == "timeout":
            raise DeviceTimeout(self.name, operation, "no reply (gave up after 4 tries)")


class SoftLamps:
    def __init__(self, rig: SoftRig):
        self.rig = rig

    @property
    def lamp_ids(self) -> tuple[str, ...]:
        return tuple(lamp.id for lamp in self.rig.config.light_arc.lamps)

    def switch(self, lamps_on) -> None:
        if lamps_on and self.rig.faults.take("lamps.switch") == "dark":
            raise DeviceFault("lamp bank", "switch", f"lamp {sorted(lamps_on)} stays dark")
        self.rig.lamps_on = frozenset(lamps_on)
        self.rig.lamp_switches.append(self.rig.lamps_on)
        if lamps_on:
            self.rig.clock.sleep(self.rig.config.lamp_bank.warmup_s)

    def lamps_on(self) -> frozenset:
        return self.rig.lamps_on

    def set_level(self, lamp_id: str, level: float) -> None:
        pass

    def close(self) -> None:
        self.rig.closed += 1


class SoftTilt:
    name = "laser tilt"
    settle_s = 0.0

    def __init__(self, rig: SoftRig):
        self.rig = rig
        self._start = (0.0, 0.0, 0.0)  # (t, from, to)

    def home(self) -> None:
        self.move_to(0.0)
        self.wait_until_settled()

    def move_to(self, deg: float) -> None:
        self._start = (self.rig.clock.now(), self.position(), deg)

    def position(self) -> float:
        t0, a, b = self._start
        speed = self.rig.config.laser.sweep_speed_deg_s
        done = min(1.0, (self.rig.clock.now() - t0) * speed / abs(b - a)) if b != a else 1.0
        return a + (b - a) * done

    def wait_until_settled(self, timeout_s: float | None = None) -> float:
        t0, a, b = self._start
        end = t0 + abs(b - a) / self.rig.config.laser.sweep_speed_deg_s
        self.rig.clock.sleep(max(0.0, end - self.rig.clock.now()))
        return b

    def stop(self) -> None:
        pass

    def close(self) -> None:
        pass


class SoftLaser:
    def __init__(self, rig: SoftRig):
        self.rig = rig
        self.tilt = SoftTilt(rig)

    def check_battery(self) -> int:
        return 8000

    def set_laser(self, on: bool, *, mount: int = 0) -> None:
        self.rig.laser_on = on

    def close(self) -> None:
        self.rig.closed += 1


class SoftCamera:
    """A ``drivers.camera.Camera`` that exposes on the soft rig: its state at the start
    of ``capture`` makes the frame, the exposure and readout pass on the rig's clock."""

    def __init__(self, rig: SoftRig, camera: str, fmt: FrameFormat):
        self.rig, self.camera_id, self.fmt = rig, camera, fmt
        self.device = f"soft camera {camera}"
        bit_depth = 8 * np.dtype(fmt.dtype).itemsize
        self.settings = CameraSettings(exposure_s=0.01, gain=1.0, bit_depth=bit_depth)
        self._sequence = 0
        self._last_t = 0.0

    def configure(
        self,
        *,
        exposure_s: float | None = None,
        gain: float | None = None,
        bit_depth: int | None = None,
    ) -> CameraSettings:
        given = {"exposure_s": exposure_s, "gain": gain, "bit_depth": bit_depth}
        self.settings = replace(self.settings, **{k: v for k, v in given.items() if v is not None})
        return self.settings

    def capture(self) -> Frame:
        rig, camera, exposure = self.rig, self.camera_id, self.settings.exposure_s
        disturbance = rig.faults.take(f"{camera}.trigger")
        if disturbance == "stray_lamp":  # a relay lights a second lamp
            stray = next(lamp for lamp in SoftLamps(rig).lamp_ids if lamp not in rig.lamps_on)
            rig.lamps_on = rig.lamps_on | {stray}
        elif disturbance == "bump":  # someone knocks the turntable half a degree on
            rig.turntable_deg += 0.5
        if rig.moving():
            rig.violations.append(("exposed while moving", camera, rig.moving()))
        if not (rig.lamps_on or rig.laser_on):
            rig.violations.append(("exposed in the dark", camera))
        readout = rig.config.camera(camera).readout_s * (self.fmt.height / 768)
        t = rig.clock.now()
        tt, arc, lamps, laser = (rig.turntable_deg, rig.arc_deg, tuple(sorted(rig.lamps_on)),
                                 rig.laser_on)  # fmt: skip
        rig.clock.sleep(exposure + readout)
        if rig.real_delay_s:
            time.sleep(rig.real_delay_s)
        fault = rig.faults.take(f"{camera}.read")
        if fault == "drop":
            raise DeviceTimeout(camera, "read", "frame dropped (gave up after 4 tries)")
        image = soft_image(self.fmt, camera, tt, arc, lamps, laser, exposure)
        rig.captures.append((camera, tt, arc, lamps, laser, exposure))
        if fault == "stale":  # the buffer's last frame again
            t = self._last_t
        self._last_t = t
        self._sequence += 1
        return Frame(image, t, exposure, self.settings.gain, self._sequence, camera)

    def close(self) -> None:
        self.rig.closed += 1


def soft_image(fmt: FrameFormat, camera, tt, arc, lamps, laser, exposure) -> np.ndarray:
    """The frame a soft camera makes for a rig state: a level fixed by the state + a ramp."""
    key = f"{camera}|{tt:.6f}|{arc:.6f}|{','.join(lamps)}|{laser}|{exposure:.6g}"
    level = 16 + zlib.crc32(key.encode()) % 200
    ramp = (np.arange(fmt.width) % 32).astype(np.int64)
    image = np.empty(fmt.shape, dtype=fmt.dtype)
    image[...] = (level + ramp)[None, :, None]
    return image


def soft_devices(rig: SoftRig):
    """A device factory (``factory(config, clock=, scale=, laser=)``) over ``rig``."""

    def factory(config: RigConfig, *, clock: Clock, scale: float, laser: bool) -> RigDevices:
        rig.opened += 1
        formats = frame_formats(config, scale=scale)
        return RigDevices(
            config,
            clock=rig.clock,
            turntable=SoftAxis(rig, "turntable", config.turntable.axis),
            arc=SoftAxis(rig, "arc", config.light_arc.axis),
            lamps=SoftLamps(rig),
            laser=SoftLaser(rig) if laser else None,
            cameras={c: ThreadedCamera(SoftCamera(rig, c, fmt), c) for c, fmt in formats.items()},
        )

    return factory
