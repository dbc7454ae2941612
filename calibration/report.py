"""The calibration report: the text a person reads and the plot they look at."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from calibration.cameras import TurntableCamera
from calibration.response import ResponseCurve
from rig.calfile import LampResult, LaserResult
from rig.geometry import direction_angles

__all__ = [
    "camera_report",
    "lamp_report",
    "laser_report",
    "plot_camera_residuals",
    "plot_lamps",
    "plot_response",
    "response_report",
]


def camera_report(cameras: dict[str, TurntableCamera], failed: dict[str, str]) -> str:
    """One line per camera: RMS, images kept and left out, focal length, centre."""
    lines = ["camera   RMS px  images  rejected  fx px     fy px     centre mm (world)"]
    for camera_id, cam in cameras.items():
        c = cam.centre_mm
        lines.append(
            f"{camera_id:<8} {cam.rms_px:6.3f}  {len(cam.per_image_rms_px):6d}  "
            f"{len(cam.rejected):8d}  {cam.K[0, 0]:8.2f}  {cam.K[1, 1]:8.2f}  "
            f"({c[0]:7.2f}, {c[1]:7.2f}, {c[2]:7.2f})"
        )
        lines += [f"         image {i}: {why}" for i, why in sorted(cam.rejected.items())]
    lines += [f"{camera_id:<8} not calibrated: {why}" for camera_id, why in failed.items()]
    return "\n".join(lines)


def plot_camera_residuals(cameras: dict[str, TurntableCamera], path: str | Path) -> Path:
    """PNG: each camera's per-image reprojection RMS (kept images)."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(8, 4), dpi=100)
    for k, cam in enumerate(cameras.values()):
        errors = np.array(list(cam.per_image_rms_px.values()))
        ax.scatter(np.full(len(errors), k), errors, s=14, alpha=0.7)
        ax.plot([k - 0.3, k + 0.3], [cam.rms_px] * 2, color="k", lw=1.5)
    ax.set_xticks(range(len(cameras)), list(cameras))
    ax.axhline(0.1, color="r", ls="--", lw=0.8, label="0.1 px")
    ax.set_ylabel("reprojection RMS per image, px")
    ax.set_title("camera calibration: per-image residuals (bar: camera RMS)")
    ax.legend(loc="upper right")
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path)
    plt.close(fig)
    return path


def laser_report(results: dict[int, LaserResult], frames) -> str:
    """Per mount the sheet angle (at the frame nearest tilt 0), its uncertainty and
    residual, and how many scan frames gave an angle."""
    lines = ["mount  angle °    ± °     residual mm  heights  tilt °  frames used"]
    for mount in sorted({f.mount for f in frames}):
        mine = [f for f in frames if f.mount == mount]
        used = sum(f.angle is not None for f in mine)
        r = results.get(mount)
        if r is None:
            reason = next((f.reason for f in mine if f.reason), "no frames")
            lines.append(f"{mount:<5}  not calibrated: {reason}")
            continue
        lines.append(
            f"{mount:<5}  {r.angle_deg:8.3f}  {r.angle_std_deg:6.3f}  {r.residual_mm:11.4f}  "
            f"{r.heights:7d}  {r.tilt_deg:6.2f}  {used}/{len(mine)}"
        )
    return "\n".join(lines)


def response_report(curves: dict[str, ResponseCurve], failed: dict[str, str]) -> str:
    """Per camera: the relative exposure at a few values (1 at 128) and the
    curve's gamma-equivalent slope in log–log between values 32 and 224."""
    lines = ["camera   E(32)    E(64)    E(192)   E(224)   log-log slope 32…224"]
    for camera_id, curve in curves.items():
        e = curve.curve.mean(axis=1).astype(np.float64)
        slope = np.log(e[224] / e[32]) / np.log(224 / 32)
        lines.append(
            f"{camera_id:<8} {e[32]:.4f}   {e[64]:.4f}   {e[192]:.4f}   {e[224]:.4f}   {slope:.3f}"
        )
    lines += [f"{camera_id:<8} not calibrated: {why}" for camera_id, why in failed.items()]
    return "\n".join(lines)


def plot_response(curves: dict[str, ResponseCurve], path: str | Path) -> Path:
    """PNG: each camera's fitted inverse response, per channel, log scale."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(6, 4), dpi=100)
    values = np.arange(256)
    for camera_id, curve in curves.items():
        for c, colour in zip(range(curve.curve.shape[1]), ("r", "g", "b"), strict=False):
            label = f"{camera_id} {colour}"
            ax.semilogy(values, curve.curve[:, c], color=colour, lw=1, label=label)
    ax.set_xlabel("pixel value")
    ax.set_ylabel("relative exposure (1 at 128)")
    ax.set_title("radiometric response (Debevec & Malik)")
    ax.legend(fontsize=7)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path)
    plt.close(fig)
    return path


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def lamp_report(results: dict[str, LampResult], run, failed: dict[str, str]) -> str:
    """Per lamp: direction (θ, φ) and distance or the direction alone, intensity,
    residual, rays used and clipped, shots that gave none."""
    lines = ["lamp      θ °      φ °     distance mm  intensity  residual  rays  clipped  no ray"]
    for lamp, r in results.items():
        vector = np.array(r.position_mm if r.position_mm is not None else r.direction)
        theta, phi = direction_angles(vector)
        near = r.position_mm is not None
        distance = f"{np.linalg.norm(vector):11.1f}" if near else f"{'∞':>11}"
        intensity = f"{r.intensity:9.4f}" if r.intensity is not None else f"{'–':>9}"
        unit = "mm" if near else "° "
        residual = f"{r.residual:6.3f}{unit}" if r.residual is not None else f"{'one ray':>8}"
        lines.append(
            f"{lamp:<8} {float(theta):6.2f}  {float(phi):7.2f}  {distance}  {intensity}  "
            f"{residual}  {r.observations:4d}  {r.clipped:7d}  "
            f"{len(run.skipped.get(lamp, [])):6d}"
        )
    lines += [f"{lamp:<8} not calibrated: {why}" for lamp, why in failed.items()]
    return "\n".join(lines)


def plot_lamps(results: dict[str, LampResult], path: str | Path) -> Path:
    """PNG: the lamps on the hemisphere seen from above (polar plot: radius θ,
    angle φ); near lamps filled, distant ones open; labels carry the intensity."""
    plt = _pyplot()
    fig = plt.figure(figsize=(5, 5), dpi=100)
    ax = fig.add_subplot(projection="polar")
    for lamp, r in results.items():
        near = r.position_mm is not None
        theta, phi = direction_angles(np.array(r.position_mm if near else r.direction))
        ax.scatter(np.deg2rad(float(phi)), float(theta), s=40,
                   facecolors="C0" if near else "none", edgecolors="C0")  # fmt: skip
        label = lamp if r.intensity is None else f"{lamp} ({r.intensity:.3f})"
        ax.annotate(label, (np.deg2rad(float(phi)), float(theta)), fontsize=7,
                    xytext=(4, 4), textcoords="offset points")  # fmt: skip
    ax.set_rmax(90)
    ax.set_title("lamps on the hemisphere (θ from the zenith)", fontsize=9)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path)
    plt.close(fig)
    return path
