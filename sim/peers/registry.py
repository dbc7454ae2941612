"""The peer registry: which simulated device answers which ``kind`` in which role.

Each peer family registers a starter per (role, kind) at import::

    @register_peer("turntable", "modbus")
    def _start(section: Turntable, world: World, *, faults, serial) -> TurntableDrivePeer: ...

``start_peer(role, section, world)`` reads the kind from
``section.device.kind``, starts the peer on ``world`` and returns it running.
Every peer has ``connect(section)`` — the section with its device pointing
at the peer (a loopback port, a pty), so the unchanged driver reaches it —
and ``stop()``. The first lookup imports every public module under
``sim/peers/``, so a new family registers itself without being listed
anywhere. Cameras are not here: the simulator's camera server stands in for
every camera kind.
"""

from __future__ import annotations

import importlib
import pkgutil
from collections.abc import Callable, Mapping
from typing import Any, Protocol

from rig.devices import DEVICE_ROLES
from rig.errors import ConfigError
from sim.world import World

__all__ = ["Peer", "register_peer", "start_peer"]


class Peer(Protocol):
    """A running simulated device."""

    def connect(self, section: Any) -> Any:
        """``section`` (the role's config section) with its device reaching this peer."""

    def stop(self) -> None:
        """Stop answering and release ports and threads; idempotent."""


Starter = Callable[..., Peer]
_STARTERS: dict[tuple[str, str], Starter] = {}
_discovered = False


def register_peer(role: str, kind: str) -> Callable[[Starter], Starter]:
    """Decorator: ``starter(section, world, *, faults, serial)`` starts ``kind`` in ``role``."""
    if role not in DEVICE_ROLES:
        raise ValueError(f"register_peer: unknown role {role!r}; valid are {list(DEVICE_ROLES)}")

    def add(starter: Starter) -> Starter:
        existing = _STARTERS.get((role, kind))
        if existing is not None and existing is not starter:
            raise ValueError(f"register_peer: {role}/{kind} is registered twice")
        _STARTERS[(role, kind)] = starter
        return starter

    return add


def start_peer(
    role: str,
    section: Any,
    world: World,
    *,
    faults: Mapping[str, Any] | None = None,
    serial: bool = False,
) -> Peer:
    """Start the peer of ``role`` for the device ``section`` describes, on ``world``.

    Parameters
    ----------
    role : one of ``rig.devices.DEVICE_ROLES``
    section : the role's section of the rig config (``config.turntable`` …)
    world : the simulated rig the peer moves and lights
    faults : the peer's fault table (keys checked by the peer)
    serial : where a family can serve a network port or a serial line (Modbus
        TCP or RTU), serve the serial line, on a pty
    """
    kind = section.device.kind
    starter = _STARTERS.get((role, kind))
    if starter is None:
        _discover()
        starter = _STARTERS.get((role, kind))
    if starter is None:
        served = sorted(k for r, k in _STARTERS if r == role)
        raise ConfigError(
            f"{role}.device: no simulated peer for kind {kind!r}; the simulator has {served}"
        )
    return starter(section, world, faults=dict(faults or {}), serial=serial)


def _discover() -> None:
    global _discovered
    if _discovered:
        return
    import sim.peers

    for module in pkgutil.iter_modules(sim.peers.__path__):
        if not module.name.startswith("_"):
            importlib.import_module(f"sim.peers.{module.name}")
    _discovered = True
