"""Rig kinds: what a rig design is, one module per kind, found by the config's ``kind``.

A rig kind (``wang``: turntable and light arc, seed 001; ``bonn``: fixed lamp,
arm and rail, seed 000; ``virtex``: fixed lamp ring, seed 004) answers every
question whose answer depends on the design (:class:`RigKind`): its config
section and how it is checked, its lamps and device roles, its kinematics, how
a plan compiles into steps and how long moves take, and what registration and
processing may assume about a recorded step. Each module of this package
registers one kind at import (``KINDS``); the first lookup of a name not yet
registered imports them all, so a new kind is found without being listed here
(docs/devices.md, "Adding a rig kind"). The simulator (``sim.kinds``) and the
daemon (``orchestrator.daemon.kinds``) keep their per-kind code the same way.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

from rig.errors import ConfigError
from rig.registry import KindRegistry

if TYPE_CHECKING:
    import numpy as np

    from rig.camera import PinholeCamera
    from rig.config import RigConfig
    from rig.parts import Lamp
    from rig.plan import Plan
    from rig.steps import Schedule, Step

__all__ = ["KINDS", "RigKind", "kind_names", "rig_kind"]

#: Rig kinds by name: ``KINDS.register("rig", name)(kind)``.
KINDS = KindRegistry("rig.kinds", roles=("rig",))


@runtime_checkable
class RigKind(Protocol):
    """One rig design. Lengths in mm, angles in degrees, times in seconds."""

    #: The ``kind`` a config names.
    name: str
    #: The config's section of this kind's own geometry (``[bonn]``), or None.
    section: str | None
    #: The device roles it opens, cameras aside, in order (``RigConfig.device_roles``).
    device_roles: tuple[str, ...]
    #: Whether the lamps ride a light arc (their place follows from arc and turntable).
    lamps_on_arc: bool

    def config_defaults(self, data: dict[str, Any]) -> dict[str, Any]:
        """A config's raw fields with the kind's defaults filled in (before validation)."""

    def check(self, config: RigConfig) -> None:
        """Raise ``ValueError`` naming the field where ``config``'s sections do not fit."""

    def lamps(self, config: RigConfig) -> tuple[Lamp, ...]:
        """The rig's lamps, in lamp-bank channel order."""

    def device_section(self, config: RigConfig, role: str) -> Any:
        """The config section of ``role`` (one of ``device_roles``); it has a ``device``."""

    def with_device_sections(self, config: RigConfig, sections: Mapping[str, Any]) -> RigConfig:
        """``config`` with the sections of some of its roles (by role) replaced."""

    def compile(self, plan: Plan, config: RigConfig) -> Schedule:
        """Ordered steps for ``plan``, with the estimate; ``PlanError`` for what it cannot do."""

    def motion_s(self, config: RigConfig, start: Any, target: Any) -> tuple[Any, Any]:
        """Move and settle time (s) between two of the kind's step poses."""

    def step_directions(
        self, config: RigConfig, step: Step
    ) -> tuple[dict[str, tuple[float, float]], tuple[float, float]]:
        """The view (θ, φ) of each of ``step``'s cameras and its light, where its pose puts
        them (sample frame, deg)."""

    def inverse(self, config: RigConfig, view_deg, light_deg) -> Any:
        """The pose nearest a wanted (view, light) pair, with ``view_residual_deg`` and
        ``light_residual_deg``; ``KinematicsError`` where the kind cannot take one."""

    def recorded_lamp_mm(
        self, config: RigConfig, lamp_id: str, actuators: Mapping[str, float]
    ) -> np.ndarray:
        """(3,) the lit lamp's position in the sample frame (mm) at a recorded step."""

    def displaced_by_deg(self, config: RigConfig, actuators: Mapping[str, float]) -> float:
        """0 when a recorded step's view and light are its place in the sampling; else the
        most each lies from the pair the plan asked for, which the rig could not reach."""

    def posed_camera(
        self, config: RigConfig, camera_id: str, actuators: Mapping[str, float]
    ) -> PinholeCamera | None:
        """The camera where a step's recorded actuators put it, for registration to fall back
        on where markers fail; None where the markers alone place the frame."""


def kind_names() -> list[str]:
    """The registered rig kinds' names."""
    return KINDS.served("rig")


def rig_kind(config_or_name: RigConfig | str) -> RigKind:
    """The kind a config (or a kind's name) names; ``ConfigError`` naming the valid ones."""
    name = config_or_name if isinstance(config_or_name, str) else config_or_name.kind
    kind = KINDS.lookup("rig", name)
    if kind is None:
        raise ConfigError(f"unknown rig kind {name!r}; valid are {kind_names()}")
    return kind
