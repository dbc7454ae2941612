"""The calibration report: the text a person reads and the plot they look at."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from calibration.cameras import TurntableCamera
from rig.calfile import LaserResult

__all__ = ["camera_report", "laser_report", "plot_camera_residuals"]


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
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

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
