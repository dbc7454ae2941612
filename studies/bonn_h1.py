"""A full H1 BTF session on the simulated Bonn lab, through the daemon and the real drivers
(UR arm, rail, lamp bank, camera) against the lab's peers: every (view, light) pair of H1
captured exactly once, every frame registered and compared with the simulator's truth
(docs/btf.md).

``rig bench bonn-h1`` (hours; ``--quick``: the first view's 81 pairs), or :func:`run` with
its options: fewer views, the render resolution, a folder to keep the archive in, or
measuring an archive a resumed run finished. Frames whose markers give no valid homography
are registered from the arm's reported tool pose and the rail (``Reason.FROM_RIG_POSE``)
and counted apart.
"""

from __future__ import annotations

import json
import logging
import tempfile
import time
from collections import defaultdict
from pathlib import Path

import numpy as np

from orchestrator.local import run_local
from processing.registration import Reason, register_frame
from rig import bonn
from rig.archive import Archive
from rig.clock import VirtualClock
from rig.geometry import Sampling, angular_distance_deg, direction_vector
from sim.rig import SimulatedRig
from studies.bonn_registration import SIZE, bonn_scene, texture_rmse

__all__ = ["run"]

log = logging.getLogger(__name__)

_PROGRESS_EVERY = 100  # steps between progress lines
ARM_POLL_S = 0.1


def _plan(views: list[tuple[float, float]]) -> str:
    listed = ", ".join(f"[{t}, {p}]" for t, p in views)
    return (
        f'[sample]\nname = "h1"\n[captures.btf]\nviews = [{listed}]\nlights = "H1"\n'
        "[exposure]\nexposure_s = 0.05\n"
    )


def _nearest(directions, direction) -> int:
    target = direction_vector(*direction)
    return min(
        range(len(directions)),
        key=lambda i: angular_distance_deg(direction_vector(*directions[i]), target),
    )


def _progress(start: float, clock: VirtualClock):
    """Logs the daemon's control address, state changes and every 100th step: the full
    session takes hours, and ``rig resume --connect`` needs the address."""

    def on_event(event: dict) -> None:
        topic = event.get("topic")
        if topic == "daemon":
            log.info("daemon control %s (rig resume --connect)", event["control"])
        elif topic == "state":
            log.info("state %s -> %s", event.get("from"), event.get("to"))
        elif topic == "progress" and (
            event["step"] % _PROGRESS_EVERY == 0 or event["step"] == event["steps"]
        ):
            log.info("step %d/%d: %.0f s here, %.0f s of rig time", event["step"],
                     event["steps"], time.perf_counter() - start, clock.now())  # fmt: skip

    return on_event


def _measure(sim, views, h1, archive_path: Path, truth_every: int) -> list[dict]:
    """One row per step: the pair it captured, registration (from the markers or the pose),
    marker reprojection, texture RMSE."""
    rig = sim.scene.rig
    rows = []
    with Archive.open(archive_path) as archive:
        for n, step in enumerate(archive.step_table()):
            rotation, rail_deg = bonn.recorded_pose(step.actuators)
            camera = bonn.camera_model(rig, "cam0", rotation, rail_deg)
            image = archive.read_frame(step.index, "cam0", 0)
            result = register_frame(image, rig.holder, size=SIZE, camera=camera, posed=camera)
            markers = result.reason == Reason.OK
            row = {
                "view": _nearest(views, step.views_deg["cam0"]),
                "light": _nearest(h1, step.light_deg),
                "valid": bool(result.valid),
                "source": "markers" if markers else "pose" if result.valid else None,
                "reproj_px": result.homography.mean_reprojection_px if markers else None,
                "rmse": None,
            }
            if result.valid and n % truth_every == 0:
                row["rmse"] = texture_rmse(
                    sim, rig, result, rotation, rail_deg,
                    exposure_s=step.exposures_s[0], bit_depth=rig.camera("cam0").bit_depth,
                )  # fmt: skip
            rows.append(row)
    return rows


def _ring_row(theta, group: list[dict]) -> dict:
    """One row of the table: the steps of one view ring (or all, ``theta`` "all")."""
    reproj = [g["reproj_px"] for g in group if g["source"] == "markers"]
    row = {
        "view_theta": theta,
        "steps": len(group),
        "pairs": len({(g["view"], g["light"]) for g in group}),
        "from_markers": len(reproj),
        "from_pose": sum(g["source"] == "pose" for g in group),
        "reproj_px_mean": float(np.mean(reproj)) if reproj else None,
        "reproj_px_p95": float(np.percentile(reproj, 95)) if reproj else None,
        "reproj_px_max": float(np.max(reproj)) if reproj else None,
    }
    for source in ("markers", "pose"):
        rmse = [100 * g["rmse"] for g in group if g["source"] == source and g["rmse"] is not None]
        row[f"rmse_pct_{source}"] = float(np.mean(rmse)) if rmse else None
        row[f"rmse_steps_{source}"] = len(rmse)
    return row


def run(
    quick: bool = False,
    *,
    views: int | None = None,
    scale: float = 0.5,
    supersample: int = 1,
    truth_every: int = 9,
    out_dir: Path | None = None,
    measure_only: bool = False,
) -> list[dict]:
    """One row per view ring θ and one over all steps (``view_theta`` "all"): steps,
    distinct (view, light) pairs, frames registered from the markers and from the pose,
    marker reprojection (px: mean, 95th percentile, max), texture RMSE (% of the truth's
    mean) of each source and the steps it was measured on.

    ``views``: the first N of H1's views, all 81 lights each (``quick``: 1; else all
    81). ``scale``, ``supersample``: the render resolution; every ``truth_every``-th
    step's normtexture is compared with ``Simulator.btf_truth``. ``out_dir``: where the
    plan, the archive (``s.zarr``) and the per-step rows (``rows.json``) stay (a
    temporary folder by default); ``measure_only``: measure the archive already there (a
    run finished with ``rig resume``).
    """
    if out_dir is None:
        if measure_only:
            raise ValueError("measure_only needs out_dir: the folder of the recorded archive")
        with tempfile.TemporaryDirectory(prefix="rig-bench-bonn-h1-") as tmp:
            return run(quick, views=views, scale=scale, supersample=supersample,
                       truth_every=truth_every, out_dir=Path(tmp))  # fmt: skip
    h1 = [tuple(map(float, d)) for d in Sampling.named("H1").directions]
    chosen = h1[: views or (1 if quick else len(h1))]
    if not measure_only:
        out_dir.mkdir(parents=True, exist_ok=True)
        (out_dir / "plan.toml").write_text(_plan(chosen))
    clock = VirtualClock()
    start = time.perf_counter()
    with SimulatedRig(bonn_scene(scale=scale, supersample=supersample), clock=clock) as sim:
        if not measure_only:
            _session(sim, out_dir, clock, start)
        steps = _measure(sim, chosen, h1, out_dir / "s.zarr", truth_every)
    (out_dir / "rows.json").write_text(json.dumps(steps))
    by_theta = defaultdict(list)
    for step in steps:
        by_theta[chosen[step["view"]][0]].append(step)
    return [*(_ring_row(t, by_theta[t]) for t in sorted(by_theta)), _ring_row("all", steps)]


def _session(sim, out: Path, clock: VirtualClock, start: float) -> None:
    """Run the plan in ``out`` through the daemon on the simulated lab."""
    config = sim.rig_config()
    # Each state read during a move waits for the peer's next real-time packet: read
    # the arm at 10 Hz of rig time, not 50, so that the wait is not the run's wall time.
    arm = config.bonn.arm.model_copy(update={"device": config.bonn.arm.device.model_copy(
        update={"poll_s": ARM_POLL_S})})  # fmt: skip
    config = config.model_copy(update={"bonn": config.bonn.model_copy(update={"arm": arm})})
    final = run_local(
        out / "plan.toml", config, archive=out / "s.zarr", clock=clock,
        on_event=_progress(start, clock), on_fault="fail",
    )  # fmt: skip
    if final["state"] != "done":
        raise RuntimeError(f"the simulated H1 session ended {final['state']}")
    log.info("session done: %.0f s here, %.0f s of rig time, %d frames exposed",
             time.perf_counter() - start, clock.now(), sim.cameras.frames_exposed)  # fmt: skip
