"""Kinematics of a Universal Robots arm: joint angles ↔ tool pose.

The arm is six revolute joints with standard Denavit–Hartenberg parameters
(``T_i = Rz(θ_i) · Tz(d_i) · Tx(a_i) · Rx(α_i)``), as Universal Robots
publishes them per model. ``forward`` gives the flange pose in the base frame;
``inverse`` solves the UR's closed form (shoulder left/right × wrist up/down ×
elbow up/down: up to 8 solutions), checks each by the forward kinematics and
returns them; ``nearest_joints`` picks the one within the joint limits that
is closest to where the arm is, or raises ``KinematicsError`` naming the pose
and why it cannot be reached.

Units follow the controller: metres and radians. A pose is the controller's
``p[x, y, z, rx, ry, rz]``: a position and a rotation vector (axis × angle).
The driver (``drivers.ur``) and the simulator's controller peer both use
this model, so a pose the driver accepts is one the arm can take.

References
----------
K. P. Hawkins, "Analytic Inverse Kinematics for the Universal Robots UR-5/UR-10
Arms", Georgia Institute of Technology, 2013.
Universal Robots, "DH parameters for calculations of kinematics and dynamics".
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rig.errors import KinematicsError

__all__ = ["UR_MODELS", "DhParameters", "Pose", "forward", "inverse", "nearest_joints"]

_FK_TOLERANCE = 1e-6  # metres / radians: a closed-form candidate that misses by more is dropped


@dataclass(frozen=True)
class DhParameters:
    """Standard DH parameters of a 6-joint UR arm (metres, radians)."""

    name: str
    d: tuple[float, float, float, float, float, float]
    a: tuple[float, float, float, float, float, float]
    alpha: tuple[float, float, float, float, float, float]

    @property
    def reach_m(self) -> float:
        """Shoulder-to-wrist reach plus the wrist offsets: no pose lies beyond it."""
        return abs(self.a[1]) + abs(self.a[2]) + self.d[3] + self.d[4] + self.d[5]


_HALF_PI = np.pi / 2
UR_MODELS = {
    "ur3e": DhParameters(
        "ur3e",
        d=(0.15185, 0.0, 0.0, 0.13105, 0.08535, 0.0921),
        a=(0.0, -0.24355, -0.2132, 0.0, 0.0, 0.0),
        alpha=(_HALF_PI, 0.0, 0.0, _HALF_PI, -_HALF_PI, 0.0),
    ),
    "ur5e": DhParameters(
        "ur5e",
        d=(0.1625, 0.0, 0.0, 0.1333, 0.0997, 0.0996),
        a=(0.0, -0.425, -0.3922, 0.0, 0.0, 0.0),
        alpha=(_HALF_PI, 0.0, 0.0, _HALF_PI, -_HALF_PI, 0.0),
    ),
    "ur10e": DhParameters(
        "ur10e",
        d=(0.1807, 0.0, 0.0, 0.17415, 0.11985, 0.11655),
        a=(0.0, -0.6127, -0.57155, 0.0, 0.0, 0.0),
        alpha=(_HALF_PI, 0.0, 0.0, _HALF_PI, -_HALF_PI, 0.0),
    ),
}


@dataclass(frozen=True)
class Pose:
    """A tool pose: ``position_m`` (3,) in metres and ``rotvec`` (3,) axis × angle in radians."""

    position_m: tuple[float, float, float]
    rotvec: tuple[float, float, float]

    def __post_init__(self) -> None:
        values = np.array([*self.position_m, *self.rotvec], dtype=np.float64)
        if values.shape != (6,) or not np.all(np.isfinite(values)):
            raise KinematicsError(
                f"a pose needs 3 finite coordinates (m) and a finite 3-vector rotation (rad); "
                f"got position {self.position_m}, rotation {self.rotvec}"
            )

    @classmethod
    def from_matrix(cls, transform) -> Pose:
        """The pose of a (4, 4) homogeneous transform."""
        t = np.asarray(transform, dtype=np.float64)
        return cls(tuple(t[:3, 3].tolist()), tuple(_rotvec(t[:3, :3]).tolist()))

    def matrix(self) -> np.ndarray:
        """(4, 4) float64 homogeneous transform of the pose."""
        t = np.eye(4)
        t[:3, :3] = _rotation(np.asarray(self.rotvec, dtype=np.float64))
        t[:3, 3] = self.position_m
        return t

    def script(self) -> str:
        """The pose in URScript: ``p[x, y, z, rx, ry, rz]``."""
        return "p[" + ", ".join(f"{v:.6f}" for v in (*self.position_m, *self.rotvec)) + "]"

    def __str__(self) -> str:
        x, y, z = (1000 * v for v in self.position_m)
        angle = np.degrees(np.linalg.norm(self.rotvec))
        return f"({x:.1f}, {y:.1f}, {z:.1f}) mm, rotated {angle:.1f}° about {_axis(self.rotvec)}"


def _axis(rotvec) -> str:
    v = np.asarray(rotvec, dtype=np.float64)
    n = np.linalg.norm(v)
    if n < 1e-12:
        return "no axis"
    return "(" + ", ".join(f"{c:.3f}" for c in v / n) + ")"


def _rotation(rotvec: np.ndarray) -> np.ndarray:
    angle = np.linalg.norm(rotvec)
    if angle < 1e-12:
        return np.eye(3)
    k = rotvec / angle
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(angle) * kx + (1 - np.cos(angle)) * kx @ kx


def _rotvec(r: np.ndarray) -> np.ndarray:
    """The rotation vector of a rotation matrix, to the matrix's own precision at any angle.

    R = cos θ·I + sin θ·[k]ₓ + (1 − cos θ)·k kᵀ: its antisymmetric part gives 2 sin θ·k, its
    symmetric part (1 − cos θ)·k kᵀ. The angle comes from both (atan2); beyond a quarter turn
    the axis comes from the symmetric part (its largest column, the sign from the
    antisymmetric part), where sin θ, falling to 0 at a half turn, would amplify rounding."""
    w = np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]])
    cos = (np.trace(r) - 1) / 2
    sin = np.linalg.norm(w) / 2
    angle = np.arctan2(sin, cos)
    if cos >= 0:
        return angle * w / (2 * sin) if sin > 0 else np.zeros(3)
    outer = ((r + r.T) / 2 - cos * np.eye(3)) / (1 - cos)
    i = int(np.argmax(np.diag(outer)))
    axis = outer[:, i] / np.sqrt(outer[i, i])
    return angle * (-axis if axis @ w < 0 else axis)


def _link(theta: float, d: float, a: float, alpha: float) -> np.ndarray:
    ct, st, ca, sa = math.cos(theta), math.sin(theta), math.cos(alpha), math.sin(alpha)
    return np.array(
        [
            [ct, -st * ca, st * sa, a * ct],
            [st, ct * ca, -ct * sa, a * st],
            [0, sa, ca, d],
            [0, 0, 0, 1],
        ]
    )


def _inverse_rigid(t: np.ndarray) -> np.ndarray:
    inv = np.eye(4)
    inv[:3, :3] = t[:3, :3].T
    inv[:3, 3] = -t[:3, :3].T @ t[:3, 3]
    return inv


def forward(joints_rad, model: DhParameters = UR_MODELS["ur5e"]) -> np.ndarray:
    """(4, 4) float64 flange pose in the base frame for the 6 joint angles (rad)."""
    q = np.asarray(joints_rad, dtype=np.float64)
    if q.shape != (6,):
        raise KinematicsError(f"{model.name}: forward needs 6 joint angles; got shape {q.shape}")
    t = np.eye(4)
    for i in range(6):
        t = t @ _link(q[i], model.d[i], model.a[i], model.alpha[i])
    return t


def inverse(transform, model: DhParameters = UR_MODELS["ur5e"]) -> np.ndarray:
    """Every joint solution (n, 6) in (−π, π] reaching the flange ``transform`` (4, 4); n ≤ 8.

    Candidates of the closed form are kept only when the forward kinematics
    reproduce ``transform``; n = 0 when the pose is out of reach. At a wrist
    singularity (joint 5 at 0 or π) joint 6 is set to 0.
    """
    t = np.asarray(transform, dtype=np.float64)
    d1, _, _, d4, d5, d6 = model.d
    a2, a3 = model.a[1], model.a[2]
    p05 = t @ np.array([0.0, 0.0, -d6, 1.0])
    r05 = np.hypot(p05[0], p05[1])
    solutions = []
    if r05 < abs(d4):
        return np.empty((0, 6))
    psi = np.arctan2(p05[1], p05[0])
    phi = np.arccos(np.clip(d4 / r05, -1.0, 1.0))
    t60 = _inverse_rigid(t)
    for q1 in (psi + phi + _HALF_PI, psi - phi + _HALF_PI):
        s1, c1 = np.sin(q1), np.cos(q1)
        c5 = (t[0, 3] * s1 - t[1, 3] * c1 - d4) / d6
        if abs(c5) > 1.0 + 1e-9:
            continue
        for q5 in (np.arccos(np.clip(c5, -1, 1)), -np.arccos(np.clip(c5, -1, 1))):
            s5 = np.sin(q5)
            if abs(s5) < 1e-9:
                q6 = 0.0
            else:
                q6 = np.arctan2(
                    (-t60[1, 0] * s1 + t60[1, 1] * c1) / s5, (t60[0, 0] * s1 - t60[0, 1] * c1) / s5
                )
            t01 = _link(q1, d1, 0.0, model.alpha[0])
            t45 = _link(q5, d5, 0.0, model.alpha[4])
            t56 = _link(q6, d6, 0.0, model.alpha[5])
            t14 = _inverse_rigid(t01) @ t @ _inverse_rigid(t45 @ t56)
            p13 = t14 @ np.array([0.0, -d4, 0.0, 1.0]) - np.array([0.0, 0.0, 0.0, 1.0])
            n13 = np.linalg.norm(p13[:3])
            c3 = (n13**2 - a2**2 - a3**2) / (2 * a2 * a3)
            if abs(c3) > 1.0 + 1e-9:
                continue
            for q3 in (np.arccos(np.clip(c3, -1, 1)), -np.arccos(np.clip(c3, -1, 1))):
                q2 = -np.arctan2(p13[1], -p13[0]) + np.arcsin(np.clip(a3 * np.sin(q3) / n13, -1, 1))
                t12 = _link(q2, 0.0, a2, model.alpha[1])
                t23 = _link(q3, 0.0, a3, model.alpha[2])
                t34 = _inverse_rigid(t12 @ t23) @ t14
                q4 = np.arctan2(t34[1, 0], t34[0, 0])
                q = _wrap(np.array([q1, q2, q3, q4, q5, q6]))
                if np.max(np.abs(forward(q, model) - t)) < _FK_TOLERANCE:
                    solutions.append(q)
    return np.array(solutions).reshape(-1, 6)


def _wrap(q: np.ndarray) -> np.ndarray:
    return np.pi - np.mod(np.pi - q, 2 * np.pi)


def nearest_joints(
    pose: Pose,
    current_rad,
    *,
    limits_rad,
    model: DhParameters = UR_MODELS["ur5e"],
    tcp: Pose | None = None,
) -> np.ndarray:
    """The joint angles (6,) reaching ``pose`` within ``limits_rad`` closest to ``current_rad``.

    Parameters
    ----------
    pose : the tool pose wanted, in the base frame
    current_rad : (6,) the joints now; each joint of each solution is shifted
        by whole turns to lie nearest it, and the solution moving the joints
        least (largest single joint move) wins
    limits_rad : (6, 2) lower and upper joint limits
    tcp : the tool centre point on the flange (None: the flange itself)

    Raises
    ------
    KinematicsError
        Naming the pose: out of reach, or every solution outside the limits.
    """
    current = np.asarray(current_rad, dtype=np.float64)
    limits = np.asarray(limits_rad, dtype=np.float64)
    flange = pose.matrix() if tcp is None else pose.matrix() @ _inverse_rigid(tcp.matrix())
    solutions = inverse(flange, model)
    if len(solutions) == 0:
        distance = np.linalg.norm(flange[:3, 3] - [0.0, 0.0, model.d[0]])
        raise KinematicsError(
            f"{model.name}: the pose {pose} is out of reach (flange {distance * 1000:.0f} mm "
            f"from the shoulder, reach {model.reach_m * 1000:.0f} mm, or a wrist orientation "
            "the arm cannot take there)"
        )
    turns = np.round((current - solutions) / (2 * np.pi))
    candidates = solutions + 2 * np.pi * turns
    for shift in (-2 * np.pi, 2 * np.pi):  # the nearest turn is outside the limits: the next
        fits = (candidates >= limits[:, 0]) & (candidates <= limits[:, 1])
        shifted = candidates + shift
        fits_shifted = (shifted >= limits[:, 0]) & (shifted <= limits[:, 1])
        candidates = np.where(~fits & fits_shifted, shifted, candidates)
    inside = np.all((candidates >= limits[:, 0]) & (candidates <= limits[:, 1]), axis=1)
    if not inside.any():
        raise KinematicsError(
            f"{model.name}: the pose {pose} is reachable only outside the joint limits "
            f"({len(solutions)} solution(s), none within "
            + ", ".join(f"[{lo:.0f}°, {hi:.0f}°]" for lo, hi in np.degrees(limits))
            + ")"
        )
    moves = np.max(np.abs(candidates[inside] - current), axis=1)
    return candidates[inside][int(np.argmin(moves))]
