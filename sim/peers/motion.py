"""Start and stop the simulated turntable drive, lamp bank and light-arc bus together.

``start_motion_peers`` starts the three peers on one ``World`` and returns a
``MotionPeers`` whose ``rig_config`` rewrites a rig config's connections so
that unchanged drivers reach them (loopback TCP ports, pty paths).
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Literal

from rig.config import RigConfig
from rig.errors import ConfigError
from sim.peers.dynamixel import DynamixelBusPeer
from sim.peers.modbus import LampBankPeer, TurntableDrivePeer
from sim.world import World

__all__ = ["MOTION_PEERS", "MotionPeers", "start_motion_peers"]

log = logging.getLogger(__name__)
MOTION_PEERS = ("turntable", "lamp_bank", "light_arc")


@dataclass
class MotionPeers:
    """The running peers; ``stop()`` stops all of them (idempotent)."""

    turntable: TurntableDrivePeer
    lamp_bank: LampBankPeer
    light_arc: DynamixelBusPeer
    transport: Literal["tcp", "rtu"]

    def rig_config(self, config: RigConfig) -> RigConfig:
        """``config`` with the turntable, lamp-bank and light-arc connections on these peers."""
        drive = _modbus(config.turntable.drive, self.turntable, self.transport)
        bank = _modbus(config.lamp_bank.connection, self.lamp_bank, self.transport)
        servos = config.light_arc.servos.model_copy(
            update={"serial_port": self.light_arc.serial_port}
        )
        return config.model_copy(
            update={
                "turntable": config.turntable.model_copy(update={"drive": drive}),
                "lamp_bank": config.lamp_bank.model_copy(update={"connection": bank}),
                "light_arc": config.light_arc.model_copy(update={"servos": servos}),
            }
        )

    def stop(self) -> None:
        for peer in (self.light_arc, self.lamp_bank, self.turntable):
            peer.stop()

    def __enter__(self) -> MotionPeers:
        return self

    def __exit__(self, *exc) -> None:
        self.stop()


def start_motion_peers(
    world: World,
    *,
    transport: Literal["tcp", "rtu"] = "tcp",
    faults: Mapping[str, Mapping[str, Any]] | None = None,
) -> MotionPeers:
    """Start the turntable drive, lamp bank and light-arc bus on ``world``.

    Parameters
    ----------
    world : World
        The simulated rig the peers move and light.
    transport : "tcp" or "rtu"
        Modbus over loopback TCP (ephemeral ports) or RTU on ptys.
    faults : mapping
        Per peer (``turntable``, ``lamp_bank``, ``light_arc``) its fault table,
        e.g. ``{"lamp_bank": {"dead_lamps": ["lamp3"]}}``.

    Returns
    -------
    MotionPeers
        Started; on a failure to start, whatever did start is stopped again.
    """
    faults = dict(faults or {})
    unknown = sorted(set(faults) - set(MOTION_PEERS))
    if unknown:
        raise ConfigError(f"faults for unknown peer(s) {unknown}; valid are {list(MOTION_PEERS)}")
    started: list[Any] = []
    try:
        turntable = TurntableDrivePeer.from_config(
            world, transport=transport, faults=faults.get("turntable")
        )
        started.append(turntable.start())
        lamp_bank = LampBankPeer.from_config(
            world, transport=transport, faults=faults.get("lamp_bank")
        )
        started.append(lamp_bank.start())
        light_arc = DynamixelBusPeer(world, faults=faults.get("light_arc"))
        started.append(light_arc.start())
    except BaseException:
        for peer in reversed(started):
            peer.stop()
        raise
    log.info(
        "motion peers: turntable %s, lamp bank %s, light arc %s",
        turntable.port if transport == "tcp" else turntable.serial_port,
        lamp_bank.port if transport == "tcp" else lamp_bank.serial_port,
        light_arc.serial_port,
    )
    return MotionPeers(turntable, lamp_bank, light_arc, transport)


def _modbus(connection, peer, transport: str):
    if transport == "tcp":
        return connection.model_copy(
            update={"protocol": "tcp", "host": "127.0.0.1", "port": peer.port}
        )
    return connection.model_copy(update={"protocol": "rtu", "serial_port": peer.serial_port})
