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

from collections.abc import Callable, Mapping
from typing import Any, Protocol

from rig.devices import ACTUATOR_ROLES
from rig.errors import ConfigError
from rig.registry import KindRegistry
from sim.world import World

__all__ = ["Peer", "register_peer", "start_peer"]


class Peer(Protocol):
    """A running simulated device."""

    def connect(self, section: Any) -> Any:
        """``section`` (the role's config section) with its device reaching this peer."""

    def stop(self) -> None:
        """Stop answering and release ports and threads; idempotent."""


_REGISTRY = KindRegistry("sim.peers", ACTUATOR_ROLES)


def register_peer(role: str, kind: str) -> Callable[[Callable], Callable]:
    """Decorator: ``starter(section, world, *, faults, serial)`` starts ``kind`` in ``role``."""
    return _REGISTRY.register(role, kind)


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
    role : one of ``rig.devices.ACTUATOR_ROLES``
    section : the role's section of the rig config (``config.turntable`` …)
    world : the simulated rig the peer moves and lights
    faults : the peer's fault table (keys checked by the peer)
    serial : where a family can serve a network port or a serial line (Modbus
        TCP or RTU), serve the serial line, on a pty
    """
    kind = section.device.kind
    starter = _REGISTRY.lookup(role, kind)
    if starter is None:
        served = _REGISTRY.served(role)
        raise ConfigError(
            f"{role}.device: no simulated peer for kind {kind!r}; the simulator has {served}"
        )
    return starter(section, world, faults=dict(faults or {}), serial=serial)
