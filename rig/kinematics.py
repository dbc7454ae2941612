"""Kinematics of the Wang rig: actuator positions ↔ sample-frame directions.

The turntable turns the sample by α about z, so a world direction with azimuth
ψ has sample azimuth ψ − α. Cameras sit at fixed signed polar angles on the
camera arc (azimuth A); lamps and laser mounts at fixed signed polar angles on
the light arc, which turns to β. Directions are those seen from the turntable
centre.

The inverse picks, among all cameras and lamps, the pair and axis positions that
come closest to a wanted (view, light) pair, breaking ties by the motion from
the current position; what it cannot hit is reported as an angular residual.

(The VirTex stage's kinematics: ``rig.kinds.virtex``; the Bonn lab's: ``rig.bonn``.)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rig.config import Axis, RigConfig, arc_direction
from rig.errors import KinematicsError
from rig.geometry import Sampling, angular_distance_deg, direction_angles, direction_vector
from rig.kinds import rig_kind

__all__ = [
    "RigPose",
    "forward",
    "inverse",
    "lamp_position_mm",
    "laser_plane",
    "laser_source_mm",
    "rotate_z",
    "sampling_residuals",
    "wrap_into",
]

@dataclass(frozen=True)
class RigPose:
    """Where the actuators go and which camera and lamp (or laser mount) act.

    ``view_residual_deg`` / ``light_residual_deg`` are the angles between the
    wanted and the achieved directions (0 when hit exactly).
    """

    turntable_deg: float
    arc_deg: float
    camera: str
    lamp: str
    view_residual_deg: float = 0.0
    light_residual_deg: float = 0.0


def rotate_z(vectors, angle_deg) -> np.ndarray:
    """Rotate (..., 3) vectors by ``angle_deg`` about +z (broadcast)."""
    v = np.asarray(vectors, dtype=np.float64)
    a = np.deg2rad(np.asarray(angle_deg, dtype=np.float64))
    c, s = np.cos(a), np.sin(a)
    return np.stack([c * v[..., 0] - s * v[..., 1], s * v[..., 0] + c * v[..., 1], v[..., 2]], -1)


def wrap_into(angle_deg, axis: Axis, near_deg=None) -> tuple[np.ndarray, np.ndarray]:
    """The angle ± k·360° inside the axis range, nearest ``near_deg`` if given.

    Returns the wrapped angles and a mask of those that fit in the range at all
    (where none fits, the nearest range end is returned and the mask is False).
    """
    a = np.asarray(angle_deg, dtype=np.float64)
    near = (axis.min_deg + axis.max_deg) / 2 if near_deg is None else near_deg
    k = np.round((near - a) / 360.0)
    best = a + 360.0 * k
    ok = np.zeros(a.shape, dtype=bool)
    chosen = np.clip(best, axis.min_deg, axis.max_deg)
    # Try the candidate nearest `near` first, then its neighbours.
    for shift in (0.0, -360.0, 360.0, -720.0, 720.0):
        cand = best + shift
        fits = (cand >= axis.min_deg - 1e-9) & (cand <= axis.max_deg + 1e-9) & ~ok
        chosen = np.where(fits, cand, chosen)
        ok |= fits
    return chosen, ok


def forward(
    config: RigConfig, *, turntable_deg: float, arc_deg: float, camera: str, lamp: str
) -> tuple[np.ndarray, np.ndarray]:
    """Sample-frame (θ, φ) of the view and the light for actuator positions.

    ``lamp`` names a lamp or a laser mount (``laser0``, ``laser1``…).

    Returns
    -------
    view, light : (2,) float64
        (θ, φ) in degrees.
    """
    cam = config.camera(camera)
    view_w = arc_direction(cam.theta_deg, config.camera_arc.azimuth_deg)
    light_w = _source_direction(config, lamp, arc_deg)
    view = np.array(direction_angles(rotate_z(view_w, -turntable_deg)))
    light = np.array(direction_angles(rotate_z(light_w, -turntable_deg)))
    return view, light


def lamp_position_mm(
    config: RigConfig, lamp: str, *, arc_deg: float, turntable_deg: float
) -> np.ndarray:
    """(3,) position of lamp ``lamp`` in the sample frame, mm (on the light arc's radius)."""
    radius = config.light_arc.radius_mm
    return rotate_z(radius * _source_direction(config, lamp, arc_deg), -turntable_deg)


def laser_source_mm(
    config: RigConfig, mount: int, *, arc_deg: float, turntable_deg: float
) -> np.ndarray:
    """(3,) position of laser mount ``mount``'s emitter in the sample frame, mm."""
    mounts = config.laser.mount_theta_deg
    if not 0 <= mount < len(mounts):
        raise KinematicsError(f"laser mount {mount} does not exist; valid are 0..{len(mounts) - 1}")
    world = config.laser.radius_mm * arc_direction(mounts[mount], arc_deg)
    return rotate_z(world, -turntable_deg)


def _source_direction(config: RigConfig, source: str, arc_deg: float) -> np.ndarray:
    """World unit vector towards lamp or laser mount ``source`` with the arc at ``arc_deg``."""
    return arc_direction(_source_theta(config, source), arc_deg)


def _source_theta(config: RigConfig, source: str) -> float:
    if source.startswith("laser"):
        mounts = config.laser.mount_theta_deg
        try:
            return mounts[int(source.removeprefix("laser"))]
        except (ValueError, IndexError):
            raise KinematicsError(
                f"unknown laser mount {source!r}; this rig has laser0..laser{len(mounts) - 1}"
            ) from None
    return config.lamp(source).theta_deg


def inverse(
    config: RigConfig,
    view_deg,
    light_deg,
    *,
    sources: str = "lamps",
    current: tuple[float, float] | None = None,
) -> RigPose:
    """The actuator positions, camera and lamp that best realise a direction pair.

    Parameters
    ----------
    view_deg, light_deg : (θ, φ) in degrees, sample frame.
    sources : ``"lamps"`` or ``"laser"`` (choose among the laser mounts).
    current : (turntable_deg, arc_deg) now; free axes stay put and ties go to
        the smaller move.
    """
    tt_axis, arc_axis = config.turntable.axis, config.light_arc.axis
    cur_tt, cur_arc = current if current is not None else (tt_axis.min_deg, arc_axis.min_deg)
    want_v = direction_vector(*view_deg)
    want_l = direction_vector(*light_deg)

    cams = config.camera_arc.cameras
    cam_theta = np.array([c.theta_deg for c in cams])
    if sources == "lamps":
        src_ids = [lamp.id for lamp in config.lamps]
        src_theta = np.array([lamp.theta_deg for lamp in config.lamps])
    elif sources == "laser":
        src_theta = np.array(config.laser.mount_theta_deg)
        src_ids = [f"laser{i}" for i in range(len(src_theta))]
    else:
        raise KinematicsError(f"sources={sources!r}; valid are 'lamps' and 'laser'")

    # Turntable per camera: bring the camera's world azimuth to the wanted φ.
    cam_az = config.camera_arc.azimuth_deg + np.where(cam_theta < 0, 180.0, 0.0)
    free_tt = (np.abs(cam_theta) < 1e-9) | (view_deg[0] < 1e-9)
    tt = np.where(free_tt, cur_tt, cam_az - view_deg[1])
    tt, _ = wrap_into(tt, tt_axis, near_deg=cur_tt)  # (M,)
    view_w = arc_direction(cam_theta, config.camera_arc.azimuth_deg)
    view_got = rotate_z(view_w, -tt)
    view_err = angular_distance_deg(view_got, want_v)  # (M,)

    # Arc per (camera, source): bring the source's world azimuth to φ_l + α.
    tt_mc = tt[:, None]
    flip = np.where(src_theta < 0, 180.0, 0.0)[None, :]
    free_arc = (np.abs(src_theta)[None, :] < 1e-9) | (light_deg[0] < 1e-9)
    arc = np.where(free_arc, cur_arc, light_deg[1] + tt_mc - flip)
    arc, _ = wrap_into(arc, arc_axis, near_deg=cur_arc)  # (M, N)
    light_w = arc_direction(src_theta[None, :], arc)
    light_got = rotate_z(light_w, -tt_mc)
    light_err = angular_distance_deg(light_got, want_l)  # (M, N)

    residual = view_err[:, None] + light_err
    motion = np.maximum(tt_axis.move_time_s(tt_mc - cur_tt), arc_axis.move_time_s(arc - cur_arc))
    # Lexicographic: residual (to 1e-6°), then motion time.
    score = np.round(residual, 6) * 1e6 + motion
    m, n = np.unravel_index(int(np.argmin(score)), score.shape)
    return RigPose(
        turntable_deg=float(tt[m]),
        arc_deg=float(arc[m, n]),
        camera=cams[m].id,
        lamp=src_ids[n],
        view_residual_deg=float(view_err[m]),
        light_residual_deg=float(light_err[m, n]),
    )


def laser_plane(
    config: RigConfig, *, arc_deg: float, mount: int, tilt_deg: float, turntable_deg: float
) -> tuple[np.ndarray, float]:
    """The laser sheet as a plane ``n · x = d`` in the sample frame (mm).

    The emitter sits at ``laser.radius_mm`` along the mount's arc direction. At
    tilt 0 its sheet contains the emitter, the turntable centre and the
    horizontal direction across the arc, so the strip on the reference plane
    runs across the arc; tilting the emitter by ``tilt_deg`` about that
    horizontal direction sweeps the strip along the arc's radial direction.

    Returns
    -------
    normal : (3,) float64 unit vector, with ``normal[2] ≥ 0``
    d : float
    """
    mounts = config.laser.mount_theta_deg
    if not 0 <= mount < len(mounts):
        raise KinematicsError(f"laser mount {mount} does not exist; valid are 0..{len(mounts) - 1}")
    source = config.laser.radius_mm * arc_direction(mounts[mount], arc_deg)
    across = np.array([-np.sin(np.deg2rad(arc_deg)), np.cos(np.deg2rad(arc_deg)), 0.0])
    normal = np.cross(across, source)
    normal /= np.linalg.norm(normal)
    # Rodrigues rotation of the normal about `across` by the tilt.
    a = np.deg2rad(tilt_deg)
    normal = (
        normal * np.cos(a)
        + np.cross(across, normal) * np.sin(a)
        + across * np.dot(across, normal) * (1 - np.cos(a))
    )
    normal = rotate_z(normal, -turntable_deg)
    source = rotate_z(source, -turntable_deg)
    if normal[2] < 0:
        normal = -normal
    return normal, float(normal @ source)


def sampling_residuals(config: RigConfig, sampling: Sampling) -> list[dict]:
    """How closely the rig achieves a sampling, ring by ring.

    Each direction is tried as a view (with a frontal light, which the rig
    always hits) and as a light (with a frontal view). Returns one row per ring:
    ``theta_deg``, ``count``, ``max_view_residual_deg``, ``max_light_residual_deg``.
    """
    solve = rig_kind(config).inverse
    rows = []
    for theta, idx in sampling.rings().items():
        view_err = light_err = 0.0
        for d in sampling.directions[idx]:
            d = (float(d[0]), float(d[1]))
            view_err = max(view_err, solve(config, d, (0.0, 0.0)).view_residual_deg)
            light_err = max(light_err, solve(config, (0.0, 0.0), d).light_residual_deg)
        rows.append(
            {
                "theta_deg": theta,
                "count": len(idx),
                "max_view_residual_deg": view_err,
                "max_light_residual_deg": light_err,
            }
        )
    return rows
