"""What the daemon needs from each kind of device, whatever family drives it.

One small synchronous interface per role; each family's driver satisfies it
(``drivers.modbus``, ``drivers.dynamixel``, ``drivers.nxt``) and talks to the
real device or to the simulator's peer on the same wire. Every rotary axis —
turntable, light arc, the laser unit's tilt — is an ``Axis``; the robot arm
holding the sample is a ``Positioner`` (``drivers.ur``). Failures raise
``drivers.errors.DeviceError`` subclasses naming device, operation and value.
Angles are in degrees. Cameras: ``drivers.camera.Camera``.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np

from rig.ur_kinematics import Pose

__all__ = ["Axis", "LampBank", "LaserUnit", "Positioner"]


@runtime_checkable
class Axis(Protocol):
    """A rotary axis: move, wait until it stopped at the target, read where it is.

    ``settle_s`` is how long the axis needs after a move before an exposure
    (vibration dying down); the caller waits it once for axes moved together.
    """

    name: str
    settle_s: float

    def home(self) -> None:
        """Make the axis ready to move, its position known, and wait.

        A drive with a homing run (the turntable) and the laser tilt end at
        0°; servos with absolute encoders switch torque on and stay put.
        """

    def move_to(self, deg: float) -> None:
        """Start a move to ``deg``; returns at once (see ``wait_until_settled``).

        A target outside the axis's range raises before anything moves.
        """

    def wait_until_settled(self, timeout_s: float | None = None) -> float:
        """Wait until the last move ends; return the position reached (deg).

        Raises ``MotionStalled`` when the axis stops short of its target,
        ``DeviceFault`` when the device reports a fault and ``DeviceTimeout``
        when it has not arrived after ``timeout_s`` (default: twice the
        expected move time plus a margin, so no wait is unbounded).
        """

    def position(self) -> float:
        """The position (deg) the device reports."""

    def stop(self) -> None:
        """Decelerate and stop now; the next wait returns where the axis stopped."""

    def close(self) -> None:
        """Release the connection; idempotent."""


@runtime_checkable
class LampBank(Protocol):
    """The switched (and perhaps dimmable) lamps on the light arc."""

    @property
    def lamp_ids(self) -> tuple[str, ...]:
        """The lamps, in the bank's channel order."""

    def switch(self, lamps_on: set[str] | frozenset[str]) -> None:
        """Light exactly ``lamps_on``, all others off; check each lit lamp glows.

        Raises ``DeviceFault`` naming a lamp that stays dark.
        """

    def lamps_on(self) -> frozenset[str]:
        """The lamps the bank reports switched on (read back)."""

    def set_level(self, lamp_id: str, level: float) -> None:
        """Dim a lamp to ``level`` in [0, 1] (banks with dimmers only)."""

    def close(self) -> None:
        """Release the connection; idempotent."""


@runtime_checkable
class LaserUnit(Protocol):
    """The laser line projector: a diode and the ``tilt`` axis sweeping its sheet."""

    tilt: Axis

    def check_battery(self) -> int:
        """The supply voltage (mV); ``DeviceFault`` when too low to scan."""

    def set_laser(self, on: bool, *, mount: int = 0) -> None:
        """Light mount ``mount``'s diode alone, or switch every diode off."""

    def close(self) -> None:
        """Diode off (best effort), release the connection; idempotent."""


@runtime_checkable
class Positioner(Protocol):
    """An arm that puts a tool — the sample plate — at a pose (``rig.ur_kinematics.Pose``).

    The sample's orientation is the tool's. Poses are checked against the
    arm's reach and joint limits before anything moves.
    """

    name: str
    settle_s: float

    def home(self) -> None:
        """Power the arm, release its brakes and wait until it can move."""

    def check_reachable(self, pose: Pose) -> np.ndarray:
        """The joint angles (rad) for ``pose``; ``KinematicsError`` naming it when unreachable."""

    def move_to(self, pose: Pose) -> None:
        """Check ``pose``, then start the move; returns at once."""

    def wait_until_settled(self, timeout_s: float | None = None) -> Pose:
        """Wait until the move ends; return the pose reached.

        Raises ``DeviceFault`` on a protective stop (naming the arm),
        ``MotionStalled`` when it ends short, ``DeviceTimeout`` after ``timeout_s``.
        """

    def pose(self) -> Pose:
        """The tool pose the arm reports."""

    def unlock_protective_stop(self) -> None:
        """Clear a protective stop so the interrupted move can be sent again."""

    def stop(self) -> None:
        """Decelerate and stop now."""

    def close(self) -> None:
        """Release the connections; idempotent."""
