"""The whole simulated rig: every device peer on one world, and the camera server.

``SimulatedRig`` is what ``rig sim SCENE`` serves. It starts, through
``sim.peers.start_peer``, the peer of every device section's ``kind`` of the
rig's kind (``RigConfig.device_roles``; a VirTex stage: its lamp bank only;
with the default Wang rig: the turntable drive and lamp bank on Modbus, the light-arc
bus on Dynamixel 2.0 on a pty, the laser brick speaking NXT direct commands on
a pty as Bluetooth SPP) and the camera server (frames rendered by the
``Simulator`` from the world's state, for every camera whatever its kind), and
it writes the rig config whose connections reach them, so an unchanged daemon
and unchanged drivers run against it.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Literal

from rig.clock import Clock, RealClock
from rig.config import RigConfig
from rig.devices import ACTUATOR_ROLES, ARM_ROLE, SimCameraConnection
from rig.errors import ConfigError
from rig.kinds import rig_kind
from sim.peers import CameraFaults, CameraServer, Peer, start_peer
from sim.scene import Scene, load_scene
from sim.simulator import Simulator
from sim.world import World

__all__ = ["FAULT_PEERS", "SimulatedRig"]

log = logging.getLogger(__name__)
FAULT_PEERS = (*ACTUATOR_ROLES, "cameras")


class SimulatedRig:
    """Start with :meth:`start` (or ``with``), stop with :meth:`stop`.

    Parameters
    ----------
    scene : Scene or the path of a scene TOML
    clock : the world's clock; a ``ScaledClock`` speeds the rig up for a
        daemon in another process, a ``VirtualClock`` serves in-process tests
    transport : Modbus over loopback ``"tcp"`` or ``"rtu"`` on ptys (peers that
        can serve either a network port or a serial line serve the serial
        line with ``"rtu"``)
    faults : per peer (``turntable``, ``lamp_bank``, ``light_arc``, ``laser``,
        ``cameras``) its fault table, e.g. ``{"cameras": {"dropped_frames": 1}}``;
        on top of the scene's ``[faults.<peer>]`` tables, key by key
    """

    def __init__(
        self,
        scene: Scene | str | Path,
        *,
        clock: Clock | None = None,
        transport: Literal["tcp", "rtu"] = "tcp",
        faults: Mapping[str, Mapping[str, Any]] | None = None,
    ):
        self.scene = scene if isinstance(scene, Scene) else load_scene(scene)
        # the scene's fault tables, with those given here on top, key by key
        merged = {peer: dict(table) for peer, table in self.scene.spec.faults.items()}
        for peer, table in (faults or {}).items():
            merged.setdefault(peer, {}).update(table)
        unknown = sorted(set(merged) - set(FAULT_PEERS))
        if unknown:
            raise ConfigError(
                f"faults for unknown peer(s) {unknown}; valid are {list(FAULT_PEERS)}"
            )
        self._faults = merged
        CameraFaults.from_table(merged.get("cameras", {}))  # a bad table fails before any start
        self._transport = transport
        self.world = World(self.scene.rig, clock or RealClock())
        self.simulator: Simulator | None = None
        self.peers: dict[str, Peer] = {}  # by role, while started
        self.cameras: CameraServer | None = None

    def start(self) -> SimulatedRig:
        try:
            self.simulator = Simulator(self.scene)
            for role in self.scene.rig.device_roles:
                self.peers[role] = start_peer(
                    role,
                    self.scene.rig.device_section(role),
                    self.world,
                    faults=self._faults.get(role),
                    serial=self._transport == "rtu",
                )
            if ARM_ROLE in self.peers:  # the plate's pose is the arm's tool pose
                self.world.arm_joints = self.peers[ARM_ROLE].state.joints_rad
            simulator = self.simulator
            self.cameras = CameraServer(
                self.world,
                lambda camera, snapshot, exposure: (
                    simulator.render(camera, snapshot, exposure).image
                ),
                faults=CameraFaults.from_table(self._faults.get("cameras", {})),
            ).start()
        except BaseException:
            self.stop()
            raise
        log.info("simulated rig %r is up; cameras at %s", self.scene.rig.name, self.cameras.url)
        return self

    def rig_config(self) -> RigConfig:
        """The scene's rig config with every connection pointing at these peers."""
        if self.cameras is None:
            raise RuntimeError("SimulatedRig.rig_config: start() the rig first")
        config = self.scene.rig
        update = {
            role: peer.connect(config.device_section(role)) for role, peer in self.peers.items()
        }
        config = rig_kind(config).with_device_sections(config, update)
        cameras = tuple(
            cam.model_copy(
                update={
                    "connection": SimCameraConnection(
                        url=self.cameras.url, retry=cam.connection.retry
                    )
                }
            )
            for cam in config.camera_arc.cameras
        )
        arc = config.camera_arc.model_copy(update={"cameras": cameras})
        return config.model_copy(update={"camera_arc": arc})

    def stop(self) -> None:
        """Stop every peer that runs and release the GL context (idempotent)."""
        if self.cameras is not None:
            self.cameras.close()
            self.cameras = None
        for role in reversed(list(self.peers)):
            self.peers.pop(role).stop()
        if self.simulator is not None:
            self.simulator.close()
            self.simulator = None

    def __enter__(self) -> SimulatedRig:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()
