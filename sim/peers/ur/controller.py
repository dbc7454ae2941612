"""A simulated Universal Robots controller: dashboard server and real-time interface.

It answers the driver (``drivers.ur``) on loopback ports with the bytes a controller
sends: the dashboard's text replies, and the 1116-byte state packets at 500 Hz (the rate
of the e-Series models the config names) carrying the joints, the tool pose by the
model's forward kinematics (``rig.ur_kinematics``), the robot and safety modes and the
program state. It runs the URScript it is sent (``movej``, ``movel``, ``set_tcp``,
``stopj``), moving the joints in joint space at the program's speed within the joint
limits; a pose it cannot reach is refused in its log and nothing moves.

Faults, at run time or from the fault table: ``protective_stop_move`` (the
n-th move from start, 1-based) stops at ``protective_stop_fraction`` (default
0.5) of its way in a protective stop, unlockable after ``unlock_delay_s``
(default 5 s, as on a controller); ``drop_connections()`` closes every
client connection. ``powered`` (default False) starts it powered, brakes
released.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from rig.devices import ARM_ROLE, UrController
from rig.errors import ConfigError
from rig.ur_kinematics import UR_MODELS, Pose
from sim.peers._faults import check_fault_keys
from sim.peers.registry import register_peer
from sim.peers.ur._controller import ControllerState
from sim.peers.ur._server import ControllerServer
from sim.world import World

__all__ = ["UrControllerPeer"]

# A pose holding the flange over the base, tool down, away from singularities.
READY_JOINTS_DEG = (0.0, -90.0, 90.0, -90.0, -90.0, 0.0)


class UrControllerPeer:
    """The controller of the arm ``device`` describes, on ``world``'s clock.

    Parameters
    ----------
    world : World
        Its clock times the motion.
    device : UrController
        The model (DH parameters) and joint limits; its ports are not used:
        the peer listens on ``dashboard_port`` / ``realtime_port`` (0: free ones).
    joints_deg : the joints at start
    power_up_s : how long powering on and releasing the brakes each take
    faults : the fault table (see the module docstring)
    """

    FAULT_KEYS = frozenset(
        {"protective_stop_move", "protective_stop_fraction", "unlock_delay_s", "powered"}
    )

    def __init__(
        self,
        world: World,
        *,
        device: UrController | None = None,
        joints_deg=READY_JOINTS_DEG,
        power_up_s: float = 0.2,
        host: str = "127.0.0.1",
        dashboard_port: int = 0,
        realtime_port: int = 0,
        faults: Mapping[str, Any] | None = None,
    ):
        faults = dict(faults or {})
        check_fault_keys("arm controller", faults, set(self.FAULT_KEYS))
        device = device or UrController()
        self.state = ControllerState(
            world.clock,
            model=UR_MODELS[device.model],
            joints_deg=joints_deg,
            limits_deg=np.column_stack([device.joint_min_deg, device.joint_max_deg]),
            power_up_s=power_up_s,
            unlock_delay_s=float(faults.get("unlock_delay_s", 5.0)),
            powered=bool(faults.get("powered", False)),
        )
        if "protective_stop_move" in faults:
            self.protective_stop(
                move=int(faults["protective_stop_move"]),
                fraction=float(faults.get("protective_stop_fraction", 0.5)),
            )
        self._server = ControllerServer(
            self.state, host=host, dashboard_port=dashboard_port, realtime_port=realtime_port
        )

    # -- fault injection -----------------------------------------------------------
    def protective_stop(self, *, move: int | None = None, fraction: float = 0.5) -> None:
        """Stop move ``move`` (default: the next one) at ``fraction`` of its way."""
        if not 0.0 < fraction < 1.0:
            raise ConfigError(f"arm controller: protective_stop_fraction={fraction} not in (0, 1)")
        self.state.arm_protective_stop(
            move=self.state.moves + 1 if move is None else move, fraction=fraction
        )

    def drop_connections(self) -> None:
        """Close every client connection (the servers keep listening)."""
        self._server.drop_connections()

    # -- what the simulated rig reads ----------------------------------------------
    def joints_deg(self) -> np.ndarray:
        """The joints (6,) now, degrees."""
        return np.degrees(self.state.joints_rad())

    def tool_pose(self) -> Pose:
        """The tool pose now (base frame)."""
        tool = self.state.snapshot()["tool_vector_actual"]
        return Pose(tuple(tool[:3]), tuple(tool[3:]))

    @property
    def errors(self) -> list[str]:
        """The controller's log of refused programs and protective stops."""
        return list(self.state.errors)

    # -- lifecycle -----------------------------------------------------------------
    @property
    def dashboard_port(self) -> int:
        return self._server.dashboard_port

    @property
    def realtime_port(self) -> int:
        return self._server.realtime_port

    def start(self) -> UrControllerPeer:
        self._server.start()
        return self

    def stop(self) -> None:
        """Close every socket and end the serving thread; idempotent."""
        self._server.stop()

    def connect(self, section):
        """``section`` with its ``device`` pointing at this peer's ports."""
        update = {
            "host": self._server.host,
            "dashboard_port": self.dashboard_port,
            "realtime_port": self.realtime_port,
        }
        return section.model_copy(update={"device": section.device.model_copy(update=update)})

    def __enter__(self) -> UrControllerPeer:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()


@register_peer(ARM_ROLE, "ur")
def start_controller(
    section, world: World, *, faults: Mapping[str, Any], serial: bool
) -> UrControllerPeer:
    """The arm's controller on loopback ports, started (a controller has no serial line)."""
    return UrControllerPeer(world, device=section.device, faults=faults).start()
