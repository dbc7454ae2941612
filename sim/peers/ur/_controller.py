"""The simulated controller's state: power, brakes, safety, the running program, the joints.

Time is the world's clock; every read brings the state up to the clock's
now. Motion is a straight line in joint space, as ``movej`` moves: the joint
with the furthest to go follows a trapezoidal profile at the program's speed
and acceleration and the others keep in step, so all start and stop together
(``movel`` is moved the same way to its target). A protective stop can be armed for a coming move:
at the given fraction of the move every joint stops where it is, the program
ends and the safety mode reads ``PROTECTIVE_STOP`` until unlocked, which the
controller refuses during the first ``unlock_delay_s``.
"""

from __future__ import annotations

import logging
import threading

import numpy as np

from rig.clock import Clock
from rig.config import Axis
from rig.errors import KinematicsError
from rig.ur_kinematics import DhParameters, Pose, forward, nearest_joints
from sim.peers.ur._script import Program, ScriptError, Statement, parse_program
from sim.world import AxisMotion

__all__ = ["ControllerState"]

log = logging.getLogger(__name__)

# robot modes and safety modes as the controller numbers them
POWER_OFF, IDLE, RUNNING = 3, 5, 7
NORMAL, PROTECTIVE_STOP = 1, 3
ROBOT_MODES = {POWER_OFF: "POWER_OFF", IDLE: "IDLE", RUNNING: "RUNNING"}
SAFETY_MODES = {NORMAL: "NORMAL", PROTECTIVE_STOP: "PROTECTIVE_STOP"}


class ControllerState:
    """Thread-safe state of one simulated arm controller."""

    def __init__(
        self,
        clock: Clock,
        *,
        model: DhParameters,
        joints_deg,
        limits_deg,
        power_up_s: float,
        unlock_delay_s: float,
        powered: bool,
    ):
        self.clock = clock
        self.model = model
        self.limits_rad = np.radians(np.asarray(limits_deg, dtype=np.float64))
        self.power_up_s = power_up_s
        self.unlock_delay_s = unlock_delay_s
        self.robot_mode = RUNNING if powered else POWER_OFF
        self.safety_mode = NORMAL
        self.program_name = "<unnamed>"
        self.tcp = Pose((0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
        self.errors: list[str] = []  # what the controller's log would show
        self.moves = 0
        self._lock = threading.RLock()
        self._epoch = clock.now()
        self._mode_change: tuple[float, int] | None = None  # (when, the mode it becomes)
        self._stopped_at = 0.0
        self._stop_plan: dict[int, float] = {}  # move number → fraction at which it stops
        self._stop_time: float | None = None
        self._start_deg = np.asarray(joints_deg, dtype=np.float64)
        self._delta_deg = np.zeros(6)
        # the leading joint's progress, 0 → its travel (deg); the others scale with it
        self._path = AxisMotion(Axis(speed_deg_s=1.0, accel_deg_s2=1.0, min_deg=0.0, max_deg=720.0))

    # -- the dashboard's commands ------------------------------------------------
    def power_on(self) -> None:
        with self._lock:
            self._update()
            if self.robot_mode == POWER_OFF:
                self._mode_change = (self.clock.now() + self.power_up_s, IDLE)

    def power_off(self) -> None:
        with self._lock:
            self._halt(self.clock.now())
            self.robot_mode, self._mode_change = POWER_OFF, None

    def brake_release(self) -> None:
        with self._lock:
            self._update()
            if self.robot_mode == IDLE:
                self._mode_change = (self.clock.now() + self.power_up_s, RUNNING)

    def unlock_protective_stop(self) -> bool:
        """Clear a protective stop; False while the controller still refuses."""
        with self._lock:
            self._update()
            if self.safety_mode != PROTECTIVE_STOP:
                return True
            if self.clock.now() - self._stopped_at < self.unlock_delay_s:
                return False
            self.safety_mode = NORMAL
            return True

    def stop_program(self) -> None:
        with self._lock:
            self._halt(self.clock.now())

    def arm_protective_stop(self, *, move: int, fraction: float) -> None:
        """Stop move number ``move`` (1-based, counted from start) at ``fraction`` of its way."""
        with self._lock:
            self._stop_plan[move] = fraction

    # -- programs ------------------------------------------------------------------
    def run_script(self, text: str) -> None:
        """Compile and start a program; a bad or impossible one is logged and does not run."""
        with self._lock:
            self._update()
            try:
                program = parse_program(text)
                if self.robot_mode != RUNNING or self.safety_mode != NORMAL:
                    raise ScriptError(
                        f"robot mode {ROBOT_MODES[self.robot_mode]}, safety mode "
                        f"{SAFETY_MODES[self.safety_mode]}: cannot run a program"
                    )
                self._run(program)
            except (ScriptError, KinematicsError) as err:
                self.errors.append(str(err))
                log.info("simulated arm controller: program refused: %s", err)

    def _run(self, program: Program) -> None:
        now = self.clock.now()
        for statement in program.statements:
            if statement.name == "set_tcp":
                self.tcp = Pose(statement.vector[:3], statement.vector[3:])
            elif statement.name == "stopj":
                self._halt(now)
            else:
                self._move(statement, now)
                self.program_name = program.name

    def _move(self, statement: Statement, now: float) -> None:
        current = self.joints_rad()
        if statement.is_pose:
            pose = Pose(statement.vector[:3], statement.vector[3:])
            target = nearest_joints(
                pose, current, limits_rad=self.limits_rad, model=self.model, tcp=self.tcp
            )
        else:
            target = np.asarray(statement.vector)
            outside = (target < self.limits_rad[:, 0]) | (target > self.limits_rad[:, 1])
            if outside.any():
                raise ScriptError(f"joint {int(np.argmax(outside)) + 1} target beyond its limit")
        speed, accel = np.degrees(statement.keyword("v")), np.degrees(statement.keyword("a"))
        self._start_deg = np.degrees(current)
        self._delta_deg = np.degrees(target) - self._start_deg
        travel = float(np.max(np.abs(self._delta_deg)))
        self._path = AxisMotion(
            Axis(speed_deg_s=speed, accel_deg_s2=accel, min_deg=0.0, max_deg=720.0),
            target_deg=travel,
            t_start=now,
        )
        self.moves += 1
        fraction = self._stop_plan.pop(self.moves, None)
        duration = float(self._path.limits.move_time_s(travel))
        self._stop_time = None if fraction is None else now + fraction * duration

    def _halt(self, t: float) -> None:
        self._start_deg = np.degrees(self._joints_rad_at(t))
        self._delta_deg = np.zeros(6)
        self._path = AxisMotion(self._path.limits, t_start=t)
        self._stop_time = None

    # -- state ---------------------------------------------------------------------
    def _update(self) -> None:
        now = self.clock.now()
        if self._mode_change is not None and now >= self._mode_change[0]:
            self.robot_mode, self._mode_change = self._mode_change[1], None
        if self._stop_time is not None and now >= self._stop_time:
            self._stopped_at = self._stop_time
            self._halt(self._stopped_at)
            self.safety_mode = PROTECTIVE_STOP
            self.errors.append("protective stop")

    def joints_rad(self) -> np.ndarray:
        return self._joints_rad_at(self.clock.now())

    def _joints_rad_at(self, t: float) -> np.ndarray:
        travel = self._path.target_deg
        progress = 1.0 if travel == 0 else self._path.position(t) / travel
        return np.radians(self._start_deg + progress * self._delta_deg)

    def snapshot(self) -> dict:
        """The fields of the state stream at the clock's now (rad, m)."""
        with self._lock:
            self._update()
            t = self.clock.now()
            q = self.joints_rad()
            q_target = np.radians(self._start_deg + self._delta_deg)
            running = self._path.is_moving(t)
            tool = Pose.from_matrix(forward(q, self.model) @ self.tcp.matrix())
            return {
                "time": t - self._epoch,
                "q_target": q_target,
                "q_actual": q,
                "tool_vector_actual": [*tool.position_m, *tool.rotvec],
                "robot_mode": self.robot_mode,
                "safety_mode": self.safety_mode,
                "safety_status": self.safety_mode,
                "program_state": 2.0 if running else 1.0,
            }

    def modes(self) -> tuple[str, str, bool]:
        """Robot mode, safety mode (names) and whether a program runs, for the dashboard."""
        state = self.snapshot()
        return (
            ROBOT_MODES[state["robot_mode"]],
            SAFETY_MODES[state["safety_mode"]],
            state["program_state"] == 2.0,
        )
