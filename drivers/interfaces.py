"""What the daemon needs from each motion and lighting device family.

One small synchronous interface per family; each real protocol has a driver
that satisfies it (``drivers.modbus``, ``drivers.dynamixel``), and the same
driver talks to the simulator's peers, which answer on the wire. Failures
raise ``drivers.errors.DeviceError`` subclasses naming device, operation and
value. Angles are in degrees.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

__all__ = ["Arc", "LampBank", "Turntable"]


@runtime_checkable
class Turntable(Protocol):
    """The rotary stage under the sample."""

    def home(self) -> None:
        """Run the homing sequence and wait until the axis is at 0°."""

    def move_to(self, deg: float) -> None:
        """Start a move to ``deg``; returns at once (see ``wait_until_settled``)."""

    def position(self) -> float:
        """The actual position (deg) the drive reports."""

    def wait_until_settled(self, timeout_s: float | None = None) -> float:
        """Wait until the last move ends; return the position (deg).

        Raises ``MotionStalled`` when the axis stops short of its target,
        ``DeviceFault`` when the drive reports a fault and ``DeviceTimeout``
        when it is still moving after ``timeout_s``.
        """

    def stop(self) -> None:
        """Decelerate and stop now."""

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
class Arc(Protocol):
    """A rotating arc (light arc) driven by one or more servos."""

    def enable(self) -> None:
        """Switch the servos' torque on and load the motion profile."""

    def disable(self) -> None:
        """Switch the servos' torque off."""

    def move_to(self, deg: float) -> None:
        """Start a move of the arc to ``deg``; returns at once."""

    def position(self) -> float:
        """The arc angle (deg) the servos report."""

    def wait_until_settled(self, timeout_s: float | None = None) -> float:
        """Wait until the move ends; return the arc angle (deg).

        Raises ``MotionStalled``, ``DeviceFault`` (a servo's hardware error)
        or ``DeviceTimeout`` like ``Turntable.wait_until_settled``.
        """

    def close(self) -> None:
        """Release the bus; idempotent."""
