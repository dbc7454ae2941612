"""The device registry: which driver opens which ``kind`` of device in which role.

Each driver family registers an opener per (role, kind) it serves, at import::

    @register("turntable", "modbus")
    def _open(section: Turntable, *, clock: Clock) -> ModbusTurntable: ...

``open_device(role, section, clock=...)`` reads the kind from
``section.device.kind`` and calls the opener. The first lookup imports every
public module under ``drivers/``, so a new family registers itself without
being listed anywhere. Roles: ``turntable``, ``light_arc`` (axes: return a
``drivers.interfaces.Axis``), ``lamp_bank`` (a ``LampBank``), ``laser`` (a
``LaserUnit``), ``arm`` (a ``Positioner``: the arm holding the sample),
``camera`` (a ``drivers.camera.Camera``).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from drivers.errors import DeviceError
from rig.clock import Clock
from rig.devices import ACTUATOR_ROLES, CAMERA_ROLE
from rig.registry import KindRegistry

__all__ = ["ROLES", "open_device", "register"]

ROLES = (*ACTUATOR_ROLES, CAMERA_ROLE)

_REGISTRY = KindRegistry("drivers", ROLES)


def register(role: str, kind: str) -> Callable[[Callable], Callable]:
    """Decorator: ``opener(section, *, clock, **options)`` opens ``kind`` devices in ``role``."""
    return _REGISTRY.register(role, kind)


def open_device(role: str, section: Any, *, clock: Clock, **options: Any) -> Any:
    """Open the device of ``role`` that ``section`` (the role's config section) describes.

    ``options`` go to the family's opener (the lamp bank takes ``lamp_ids``;
    the NXT takes ``usb_backend``). Raises ``DeviceError`` naming the role and
    kind when no family serves them, and whatever the driver raises on open.
    """
    kind = section.device.kind
    opener = _REGISTRY.lookup(role, kind)
    if opener is None:
        served = _REGISTRY.served(role)
        raise DeviceError(
            role, "open", f"no driver for kind {kind!r}; the installed drivers serve {served}"
        )
    return opener(section, clock=clock, **options)
