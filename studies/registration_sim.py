"""The registration table of ``docs/btf.md``: every H1 view up to θ = 75° in the simulator.

``rig bench registration-sim --plot docs/img/registration_h1.png`` (about 2 minutes on 2
cores) prints the rows and draws the figure; :func:`summary` and :func:`markdown` make the
docs' two tables of them. The same measurement on the six views of
:data:`QUICK_VIEWS` is ``--quick``, and the claims of ``test_registration_sim_accuracy.py``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from studies.registration_views import SimRegistration, h1_views

__all__ = ["QUICK_VIEWS", "markdown", "plot", "run", "summary"]

#: One view per H1 ring up to 68°, two at 68° (the sparsest marker view, φ = 270°:
#: the far markers are the most foreshortened, 4–6 of them are found).
QUICK_VIEWS = ((0.0, 0.0), (17.0, 60.0), (34.0, 150.0), (51.0, 220.0), (68.0, 18.0), (68.0, 270.0))


def run(
    quick: bool = False, *, scale: float = 0.5, oversample: int = 3, size: int = 64
) -> list[dict]:
    """One row per H1 view (θ ≤ 75°; ``quick``: :data:`QUICK_VIEWS`): anti-aliased and
    point-sampled frames."""
    views = QUICK_VIEWS if quick else h1_views()
    rows = []
    with (
        SimRegistration(scale=scale, oversample=oversample, size=size) as smooth,
        SimRegistration(scale=scale, oversample=1, size=size) as point,
    ):
        for view in views:
            r = smooth.run(view)
            p = point.run(view)
            rows.append({
                "theta": r.view_deg[0], "phi": r.view_deg[1], "camera": r.camera,
                "achieved_theta": r.achieved_view_deg[0], "markers": len(r.clean.detection),
                "valid": r.clean.valid, "reason": r.clean.reason.name,
                "reproj_px": r.clean.homography.mean_reprojection_px,
                "corner_px": r.corner_error_px,
                "noisy_reproj_px": r.noisy.homography.mean_reprojection_px,
                "rmse": r.texture_rmse, "noisy_rmse": r.noisy_texture_rmse,
                "noise_rmse": r.noise_rmse, "gain": r.texture_gain,
                "point_valid": p.clean.valid,
                "point_reproj_px": p.clean.homography.mean_reprojection_px,
                "point_corner_px": p.corner_error_px,
            })  # fmt: skip
    return rows


def markdown(rows: list[dict]) -> str:
    """The per-view table of docs/btf.md."""
    head = (
        "| view θ, φ | camera (θ) | markers | reproj. px | corner vs truth px | "
        "noisy reproj. px | texture RMSE % | noisy % | noise alone % | point-sampled corner px |\n"
        "|---|---|---|---|---|---|---|---|---|---|\n"
    )
    lines = [
        f"| {r['theta']:.0f}°, {r['phi']:.0f}° | {r['camera']} ({r['achieved_theta']:.0f}°) | "
        f"{r['markers']} | {r['reproj_px']:.3f} | {r['corner_px']:.3f} | "
        f"{r['noisy_reproj_px']:.3f} | {100 * r['rmse']:.2f} | {100 * r['noisy_rmse']:.2f} | "
        f"{100 * r['noise_rmse']:.2f} | {r['point_corner_px']:.3f} |"
        for r in rows
    ]
    return head + "\n".join(lines)


def summary(rows: list[dict]) -> str:
    """The per-ring table of docs/btf.md and its closing line over all views."""
    out = []
    thetas = sorted({r["theta"] for r in rows})
    for theta in thetas:
        ring = [r for r in rows if r["theta"] == theta]
        out.append(
            f"| {theta:.0f}° | {len(ring)} | {sum(r['valid'] for r in ring)} | "
            f"{np.mean([r['reproj_px'] for r in ring]):.3f} | "
            f"{np.max([r['reproj_px'] for r in ring]):.3f} | "
            f"{np.mean([r['corner_px'] for r in ring]):.3f} | "
            f"{100 * np.mean([r['rmse'] for r in ring]):.2f} | "
            f"{100 * np.mean([r['noisy_rmse'] for r in ring]):.2f} | "
            f"{np.mean([r['point_corner_px'] for r in ring]):.3f} |"
        )
    head = (
        "| ring θ | views | valid | mean reproj. px | max reproj. px | corner vs truth px | "
        "texture RMSE % | noisy % | point-sampled corner px |\n"
        "|---|---|---|---|---|---|---|---|---|\n"
    )
    mean_reproj = np.mean([r["reproj_px"] for r in rows])
    total = (
        f"\nAll {len(rows)} views: mean reprojection {mean_reproj:.3f} px "
        f"(noisy {np.mean([r['noisy_reproj_px'] for r in rows]):.3f}), corner error against the "
        f"true projection {np.mean([r['corner_px'] for r in rows]):.3f} px, point-sampled frames "
        f"{np.mean([r['point_corner_px'] for r in rows]):.3f} px; texture gain "
        f"{np.min([r['gain'] for r in rows]):.4f}–{np.max([r['gain'] for r in rows]):.4f}."
    )
    return head + "\n".join(out) + total


def plot(rows: list[dict], path: Path) -> None:
    """Corner error and texture RMSE against the view θ (PNG)."""
    theta = np.array([r["theta"] for r in rows])
    jitter = np.array([r["phi"] for r in rows]) / 360.0 * 4 - 2
    fig = Figure(figsize=(10, 3.8))
    ax0, ax1 = fig.subplots(1, 2)
    ax0.scatter(theta + jitter, [r["corner_px"] for r in rows], s=14, label="anti-aliased, clean")
    ax0.scatter(theta + jitter, [r["noisy_reproj_px"] for r in rows], s=14, marker="x",
                label="anti-aliased, noisy (fit residual)")  # fmt: skip
    ax0.scatter(theta + jitter, [r["point_corner_px"] for r in rows], s=14, marker="^",
                label="point-sampled, clean")  # fmt: skip
    ax0.axhline(0.1, color="grey", lw=0.8, ls="--")
    ax0.set_xlabel("view θ (°), spread by φ")
    ax0.set_ylabel("marker corner error (px)")
    ax0.set_title("corners vs their true projection")
    ax0.legend(fontsize=7)
    ax1.scatter(theta + jitter, [100 * r["rmse"] for r in rows], s=14, label="clean")
    ax1.scatter(theta + jitter, [100 * r["noisy_rmse"] for r in rows], s=14, marker="x",
                label="noisy")  # fmt: skip
    ax1.scatter(theta + jitter, [100 * r["noise_rmse"] for r in rows], s=14, marker=".",
                label="noise alone")  # fmt: skip
    ax1.set_xlabel("view θ (°), spread by φ")
    ax1.set_ylabel("RMSE (% of mean)")
    ax1.set_title("64² normtexture vs btf_truth")
    ax1.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
