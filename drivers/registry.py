"""The device registry: which driver opens which ``kind`` of device in which role.

Each driver family registers an opener per (role, kind) it serves, at import::

    @register("turntable", "modbus")
    def _open(section: Turntable, *, clock: Clock) -> ModbusTurntable: ...

``open_device(role, section, clock=...)`` reads the kind from
``section.device.kind`` and calls the opener. The first lookup imports every
public module under ``drivers/``, so a new family registers itself without
being listed anywhere. Roles: ``turntable``, ``light_arc`` (axes: return a
``drivers.interfaces.Axis``), ``lamp_bank`` (a ``LampBank``), ``laser`` (a
``LaserUnit``), ``camera`` (a ``drivers.camera.Camera``).
"""

from __future__ import annotations

import importlib
import pkgutil
from collections.abc import Callable
from typing import Any

from drivers.errors import DeviceError
from rig.clock import Clock
from rig.devices import DEVICE_ROLES

__all__ = ["ROLES", "open_device", "register"]

ROLES = (*DEVICE_ROLES, "camera")

Opener = Callable[..., Any]
_OPENERS: dict[tuple[str, str], Opener] = {}
_discovered = False


def register(role: str, kind: str) -> Callable[[Opener], Opener]:
    """Decorator: ``opener(section, *, clock, **options)`` opens ``kind`` devices in ``role``."""
    if role not in ROLES:
        raise ValueError(f"register: unknown role {role!r}; valid are {list(ROLES)}")

    def add(opener: Opener) -> Opener:
        existing = _OPENERS.get((role, kind))
        if existing is not None and existing is not opener:
            raise ValueError(f"register: {role}/{kind} is registered twice")
        _OPENERS[(role, kind)] = opener
        return opener

    return add


def open_device(role: str, section: Any, *, clock: Clock, **options: Any) -> Any:
    """Open the device of ``role`` that ``section`` (the role's config section) describes.

    ``options`` go to the family's opener (the lamp bank takes ``lamp_ids``;
    the NXT takes ``usb_backend``). Raises ``DeviceError`` naming the role and
    kind when no family serves them, and whatever the driver raises on open.
    """
    kind = section.device.kind
    opener = _OPENERS.get((role, kind))
    if opener is None:
        _discover()
        opener = _OPENERS.get((role, kind))
    if opener is None:
        served = sorted(k for r, k in _OPENERS if r == role)
        raise DeviceError(
            role, "open", f"no driver for kind {kind!r}; the installed drivers serve {served}"
        )
    return opener(section, clock=clock, **options)


def _discover() -> None:
    global _discovered
    if _discovered:
        return
    import drivers

    for module in pkgutil.iter_modules(drivers.__path__):
        if not module.name.startswith("_"):
            importlib.import_module(f"drivers.{module.name}")
    _discovered = True
