"""A Universal Robots arm holding the sample, over the controller's TCP interfaces.

Public API (``drivers.interfaces.Positioner``), all poses ``rig.ur_kinematics.Pose``
(metres, rotation vector in radians) of the tool centre point in the base frame:

- ``UrArm(device, clock=…, name="arm")`` connects (dashboard + real-time port)
  and takes the device lock; ``open_device("arm", section, clock=…)`` does
  the same for a config section whose ``device`` is a ``UrController``.
- ``home()`` powers the arm on and releases the brakes (dashboard), waiting
  until the controller reports ``RUNNING`` and a normal safety status.
- ``check_reachable(pose)`` → joint angles (rad): the arm's closed-form
  inverse kinematics, nearest the present joints within the joint limits;
  ``KinematicsError`` naming the arm and the pose when none exists.
- ``move_to(pose)`` checks as above, then sends ``movej`` with those joint
  angles; returns at once. ``wait_until_settled()`` returns the pose reached.
- ``pose()`` (the TCP pose of the joints the controller reports),
  ``joints_deg()``, ``status()`` read back; ``stop()`` sends ``stopj``.
- ``unlock_protective_stop()`` clears a protective stop (dashboard); the
  move it interrupted must then be sent again.
- ``close()``.

Faults: a protective stop (or any non-normal safety mode) while waiting →
``DeviceFault`` naming the arm, the mode and where it stopped; the program
ending short of the target → ``MotionStalled``; a dropped connection is
reconnected within the configured retries, then ``DeviceTimeout``.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from drivers._lock import DeviceLock
from drivers.errors import DeviceError, DeviceFault, DeviceTimeout, MotionStalled
from drivers.registry import register
from drivers.retry import with_retries
from drivers.ur._dashboard import Dashboard
from drivers.ur._realtime import RobotMode, RobotState, SafetyMode, StateStream
from rig.clock import Clock
from rig.config import Axis
from rig.devices import ARM_ROLE, UrController
from rig.errors import KinematicsError
from rig.ur_kinematics import UR_MODELS, Pose, forward, nearest_joints

__all__ = ["ArmStatus", "UrArm"]

log = logging.getLogger(__name__)

_POWER_UP_S = 60.0  # a controller boots its joints in ~20–40 s
# A sent script shows as a running program within this much time and this many state
# packets (both: in virtual time the clock may race ahead of the controller's cycles).
_START_GRACE_S = 1.0
_START_GRACE_PACKETS = 50
_MOVING_SAFETY = (SafetyMode.NORMAL, SafetyMode.REDUCED)


class UrArm:
    """Driver of a UR arm; satisfies ``drivers.interfaces.Positioner`` (see the module doc)."""

    def __init__(self, device: UrController, *, clock: Clock, name: str = "arm"):
        self.name = name
        self.device = device
        self.settle_s = device.settle_s
        self.model = UR_MODELS[device.model]
        self.tcp = Pose(device.tcp[:3], device.tcp[3:])
        self._clock = clock
        self._poll_s = device.poll_s
        self._limits_rad = np.radians(np.column_stack([device.joint_min_deg, device.joint_max_deg]))
        self._joint_axis = Axis(
            speed_deg_s=device.joint_speed_deg_s,
            accel_deg_s2=device.joint_accel_deg_s2,
            settle_s=device.settle_s,
            min_deg=-360.0,
            max_deg=360.0,
        )
        self._target: tuple[Pose, np.ndarray] | None = None
        self._stopping = False  # a stopj was sent and no wait has seen the arm at rest yet
        self._sent_at = 0.0
        self._lock = DeviceLock(f"ur:tcp://{device.host}:{device.realtime_port}", device=name)
        self._dashboard: Dashboard | None = None
        self._stream: StateStream | None = None
        try:
            self._read_state("connect")
            self._request("robotmode", "connect")
        except BaseException:
            self.close()
            raise

    # -- power and safety ----------------------------------------------------------
    def home(self) -> None:
        """Power on, release the brakes, wait until ``RUNNING`` with a normal safety status."""
        self._expect("power on", "Powering on", "home")
        self._wait_mode({"IDLE", "RUNNING"}, "home")
        self._expect("brake release", "Brake releasing", "home")
        self._wait_mode({"RUNNING"}, "home")
        safety = self._dashboard_mode("safetystatus", "Safetystatus", "home")
        if safety != "NORMAL":
            raise DeviceFault(self.name, "home", f"safety status {safety} after brake release")

    def unlock_protective_stop(self) -> None:
        """Clear a protective stop; retried while the controller refuses (within 5 s of it)."""
        if self._dashboard_mode("safetystatus", "Safetystatus", "unlock") != "PROTECTIVE_STOP":
            return
        self._request("close safety popup", "unlock")
        give_up = self._clock.now() + self.device.unlock_wait_s
        while True:
            reply = self._request("unlock protective stop", "unlock")
            if reply.startswith("Protective stop releasing"):
                break
            if self._clock.now() >= give_up:
                raise DeviceFault(
                    self.name,
                    "unlock",
                    f"the controller refuses to unlock the protective stop: {reply!r}",
                )
            self._clock.sleep(0.5)
        self._wait_mode({"RUNNING"}, "unlock")
        log.info("%s: protective stop unlocked", self.name)

    def status(self) -> ArmStatus:
        """What the dashboard reports: robot mode, safety status, program state."""
        return ArmStatus(
            robot_mode=self._dashboard_mode("robotmode", "Robotmode", "status"),
            safety_status=self._dashboard_mode("safetystatus", "Safetystatus", "status"),
            program_state=self._request("programState", "status"),
        )

    # -- motion --------------------------------------------------------------------
    def check_reachable(self, pose: Pose, *, from_joints_rad=None) -> np.ndarray:
        """The joint angles (6,) rad reaching ``pose``, nearest ``from_joints_rad`` (default: now).

        Raises ``KinematicsError`` naming the arm and the pose when the arm
        cannot take it within its reach and joint limits.
        """
        near = self._read_state("check").q_actual if from_joints_rad is None else from_joints_rad
        try:
            return nearest_joints(
                pose, near, limits_rad=self._limits_rad, model=self.model, tcp=self.tcp
            )
        except KinematicsError as err:
            raise KinematicsError(f"{self.name}: cannot move to {pose}: {err}") from err

    def move_to(self, pose: Pose) -> None:
        """Check ``pose`` is reachable, then start a joint move there; returns at once."""
        joints = self.check_reachable(pose)
        a = np.radians(self.device.joint_accel_deg_s2)
        v = np.radians(self.device.joint_speed_deg_s)
        script = (
            "def btfrig_move():\n"
            f"  set_tcp({self.tcp.script()})\n"
            f"  movej([{', '.join(f'{q:.6f}' for q in joints)}], a={a:.4f}, v={v:.4f})\n"
            "end\n"
        )
        self._send(script, "move_to")
        self._target = (pose, joints)
        self._sent_at = self._clock.now()
        self._stopping = False

    def wait_until_settled(self, timeout_s: float | None = None) -> Pose:
        """Wait until the move ends at its target; return the pose the arm reports.

        Raises ``DeviceFault`` on a protective stop (or another safety stop)
        or when the arm is not powered, ``MotionStalled`` when the program
        ends short of the target, ``DeviceTimeout`` after ``timeout_s``
        (default: twice the slowest joint's move time plus 2 s).
        """
        if self._target is None:
            return self._pose_of(self._at_rest(timeout_s)) if self._stopping else self.pose()
        target_pose, target_q = self._target
        state = self._read_state("move_to")
        if timeout_s is None:
            delta = np.degrees(np.max(np.abs(target_q - state.q_actual)))
            timeout_s = 2.0 * float(self._joint_axis.move_time_s(delta)) + 2.0
        deadline = self._clock.now() + timeout_s
        seen_running = False
        packets = 1
        tolerance = np.radians(self.device.position_tolerance_deg)
        while True:
            self._check_safety(state, f"moving to {target_pose}")
            arrived = np.max(np.abs(state.q_actual - target_q)) <= tolerance
            seen_running |= state.program_running
            if not state.program_running and arrived:
                self._target = None
                return self._pose_of(state)
            if not state.program_running and (
                seen_running
                or (
                    self._clock.now() - self._sent_at > _START_GRACE_S
                    and packets > _START_GRACE_PACKETS
                )
            ):
                raise MotionStalled(
                    self.name,
                    "move_to",
                    f"the controller ended the move at {self._pose_of(state)}, short of "
                    f"{target_pose} (joints off by up to "
                    f"{np.degrees(np.max(np.abs(state.q_actual - target_q))):.2f}°); "
                    "see the controller's log",
                )
            if self._clock.now() >= deadline:
                raise DeviceTimeout(
                    self.name, "move_to", f"still moving to {target_pose} after {timeout_s:.1f} s"
                )
            self._clock.sleep(self._poll_s)
            state = self._read_state("move_to")
            packets += 1

    def stop(self) -> None:
        """Decelerate every joint and end the program; the next wait returns where it stopped."""
        self._send(f"stopj({np.radians(self.device.joint_accel_deg_s2):.4f})\n", "stop")
        self._target = None
        self._stopping = True

    def _at_rest(self, timeout_s: float | None) -> RobotState:
        """The first state after a ``stop()`` whose program has ended and whose joints are
        at their targets: the controller has taken the stop, however late its packet is."""
        tolerance = np.radians(self.device.position_tolerance_deg)
        if timeout_s is None:  # twice the time from full speed to rest, plus 2 s as for a move
            timeout_s = 2.0 * self.device.joint_speed_deg_s / self.device.joint_accel_deg_s2 + 2.0
        deadline = self._clock.now() + timeout_s
        state = self._read_state("stop")
        while state.program_running or np.max(np.abs(state.q_actual - state.q_target)) > tolerance:
            if self._clock.now() >= deadline:
                raise DeviceTimeout(
                    self.name, "stop", f"still moving {timeout_s:.1f} s after the stopj"
                )
            self._clock.sleep(self._poll_s)
            state = self._read_state("stop")
        self._stopping = False
        return state

    def pose(self) -> Pose:
        """The tool pose of the joint angles the controller reports (``q_actual``)."""
        return self._pose_of(self._read_state("pose"))

    def joints_deg(self) -> np.ndarray:
        """The joint angles (6,) the controller reports, degrees."""
        return np.degrees(self._read_state("joints").q_actual)

    def close(self) -> None:
        """Close both connections and release the lock; idempotent. The arm stays where it is."""
        for link in (self._stream, self._dashboard):
            if link is not None:
                link.close()
        self._stream = self._dashboard = None
        self._lock.release()

    # -- internals -----------------------------------------------------------------
    def _check_safety(self, state: RobotState, doing: str) -> None:
        if state.safety_mode not in _MOVING_SAFETY:
            raise DeviceFault(
                self.name,
                "move_to",
                f"{state.safety_mode.name.lower().replace('_', ' ')} at {self._pose_of(state)} "
                f"while {doing}; inspect the cause, then unlock_protective_stop() and repeat "
                "the move",
            )
        if state.robot_mode != RobotMode.RUNNING:
            raise DeviceFault(
                self.name,
                "move_to",
                f"robot mode {state.robot_mode.name} while {doing}; power on and release the "
                "brakes (home())",
            )

    def _pose_of(self, state: RobotState) -> Pose:
        # From the joints, not the controller's tool vector: that follows whichever
        # TCP the controller has active, which may not be ours between moves.
        flange = forward(state.q_actual, self.model)
        return Pose.from_matrix(flange @ self.tcp.matrix())

    def _read_state(self, operation: str) -> RobotState:
        return self._retried(lambda: self._on_stream(StateStream.latest), operation)

    def _send(self, script: str, operation: str) -> None:
        self._retried(lambda: self._on_stream(lambda s: s.send_script(script)), operation)

    def _on_stream(self, use):
        """``use(stream)`` on the real-time link, (re)connecting it; a failed link is dropped."""
        if self._stream is None:
            self._stream = StateStream(
                self.device.host,
                self.device.realtime_port,
                timeout_s=self.device.retry.timeout_s,
                device=self.name,
            )
        try:
            return use(self._stream)
        except DeviceError:
            self._stream.close()
            self._stream = None
            raise

    def _request(self, command: str, operation: str) -> str:
        def attempt() -> str:
            if self._dashboard is None:
                self._dashboard = Dashboard(
                    self.device.host,
                    self.device.dashboard_port,
                    timeout_s=self.device.retry.timeout_s,
                    device=self.name,
                )
            try:
                return self._dashboard.request(command)
            except DeviceError:
                self._dashboard.close()
                self._dashboard = None
                raise

        return self._retried(attempt, operation)

    def _retried(self, attempt, operation: str):
        return with_retries(
            attempt,
            retry=self.device.retry,
            clock=self._clock,
            device=self.name,
            operation=operation,
        )

    def _dashboard_mode(self, command: str, prefix: str, operation: str) -> str:
        reply = self._request(command, operation)
        head, _, value = reply.partition(":")
        if head.strip().lower() != prefix.lower() or not value.strip():
            raise DeviceError(
                self.name, operation, f"expected '{prefix}: <mode>' to {command!r}, got {reply!r}"
            )
        return value.strip()

    def _expect(self, command: str, reply_start: str, operation: str) -> None:
        reply = self._request(command, operation)
        if not reply.startswith(reply_start):
            raise DeviceFault(self.name, operation, f"{command!r} refused: {reply!r}")

    def _wait_mode(self, modes: set[str], operation: str) -> None:
        deadline = self._clock.now() + _POWER_UP_S
        while (mode := self._dashboard_mode("robotmode", "Robotmode", operation)) not in modes:
            if self._clock.now() >= deadline:
                raise DeviceTimeout(
                    self.name,
                    operation,
                    f"robot mode {mode} after {_POWER_UP_S:.0f} s, "
                    f"not {' or '.join(sorted(modes))}",
                )
            self._clock.sleep(0.1)


@dataclass(frozen=True)
class ArmStatus:
    """The dashboard's view of the arm (``robotmode``, ``safetystatus``, ``programState``)."""

    robot_mode: str
    safety_status: str
    program_state: str


@register(ARM_ROLE, "ur")
def open_arm(section, *, clock: Clock) -> UrArm:
    """The arm of a rig config section whose ``device`` is a ``UrController``."""
    return UrArm(section.device, clock=clock)
