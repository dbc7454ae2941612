"""A full H1 BTF session on the simulated Bonn lab, through the daemon and the real drivers
(UR arm, rail, lamp bank, camera) against the lab's peers: every (view, light) pair of H1
captured exactly once, every frame registered and compared with the simulator's truth
(docs/btf.md).

Run as ``python -m tests.integration.bonn_h1 [--views N] [--scale S] [--supersample K]
[--truth-every M] [--measure-only] [--rows PATH] OUT_DIR``: ``--views`` keeps the first N of
H1's views (all 81 lights each) for a shorter run; ``--scale`` and ``--supersample`` set the
render resolution; every M-th step's normtexture is compared with ``Simulator.btf_truth``;
``--measure-only`` measures the archive already in OUT_DIR (a run finished with ``rig
resume``). Frames whose markers give no valid homography are registered from the arm's
reported tool pose and the rail (``Reason.FROM_RIG_POSE``) and counted apart. The rows go to
``--rows`` (default OUT_DIR/rows.json).
"""

from __future__ import annotations

import argparse
import json
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
    def on_event(event: dict) -> None:
        topic = event.get("topic")
        if topic == "daemon":
            print(f"daemon control {event['control']} (rig resume --connect)", flush=True)
        elif topic == "state":
            print(f"state {event.get('from')} -> {event.get('to')}", flush=True)
        elif topic == "progress" and (
            event["step"] % _PROGRESS_EVERY == 0 or event["step"] == event["steps"]
        ):
            print(
                f"step {event['step']}/{event['steps']}: {time.perf_counter() - start:.0f} s "
                f"here, {clock.now():.0f} s of rig time",
                flush=True,
            )

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


def _report(rows: list[dict], views, h1) -> None:
    seen = {(r["view"], r["light"]) for r in rows}
    reproj = np.array([r["reproj_px"] for r in rows if r["source"] == "markers"])
    n_pose = sum(r["source"] == "pose" for r in rows)
    print(f"steps {len(rows)}, distinct pairs {len(seen)} of {len(views) * len(h1)}, "
          f"registered from the markers {len(reproj)}, from the pose {n_pose}, not registered "
          f"{len(rows) - len(reproj) - n_pose}")  # fmt: skip
    print(f"mean marker reprojection {reproj.mean():.3f} px (p95 "
          f"{np.percentile(reproj, 95):.3f}, max {reproj.max():.3f})")  # fmt: skip
    for source in ("markers", "pose"):
        rmse = np.array([r["rmse"] for r in rows if r["source"] == source and r["rmse"]])
        if len(rmse):
            print(f"texture RMSE from the {source} {100 * rmse.mean():.2f} % (p95 "
                  f"{100 * np.percentile(rmse, 95):.2f}, max {100 * rmse.max():.2f}) over "
                  f"{len(rmse)} steps")  # fmt: skip
    by_theta = defaultdict(list)
    for r in rows:
        by_theta[views[r["view"]][0]].append(r)
    print("| view θ | steps | from markers | from pose | reproj. px mean | reproj. px max | "
          "texture RMSE % markers (steps) | texture RMSE % pose (steps) |\n"
          "|---|---|---|---|---|---|---|---|")  # fmt: skip
    for theta in sorted(by_theta):
        group = by_theta[theta]
        r = [g["reproj_px"] for g in group if g["source"] == "markers"]
        reproj = f"{np.mean(r):.3f} | {np.max(r):.3f}" if r else "– | –"
        cells = []
        for source in ("markers", "pose"):
            e = [100 * g["rmse"] for g in group if g["source"] == source and g["rmse"] is not None]
            cells.append(f"{np.mean(e):.2f} ({len(e)})" if e else "– (0)")
        n_pose = sum(g["source"] == "pose" for g in group)
        print(f"| {theta:.0f}° | {len(group)} | {len(r)} | {n_pose} | {reproj} | "
              f"{cells[0]} | {cells[1]} |")  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("--views", type=int, default=81)
    parser.add_argument("--scale", type=float, default=0.5, help="render scale of the camera")
    parser.add_argument("--supersample", type=int, default=1, help="area samples per pixel side")
    parser.add_argument("--truth-every", type=int, default=9, help="texture RMSE every M steps")
    parser.add_argument(
        "--measure-only", action="store_true", help="measure the archive in OUT_DIR, no session"
    )
    parser.add_argument("--rows", type=Path, help="where the rows go (OUT_DIR/rows.json)")
    args = parser.parse_args()
    h1 = [tuple(map(float, d)) for d in Sampling.named("H1").directions]
    views = h1[: args.views]
    if not args.measure_only:
        args.out.mkdir(parents=True, exist_ok=True)
        (args.out / "plan.toml").write_text(_plan(views))
    clock = VirtualClock()
    start = time.perf_counter()
    scene = bonn_scene(scale=args.scale, supersample=args.supersample)
    with SimulatedRig(scene, clock=clock) as sim:
        if not args.measure_only:
            _session(sim, args.out, clock, start)
        rows = _measure(sim, views, h1, args.out / "s.zarr", args.truth_every)
    (args.rows or args.out / "rows.json").write_text(json.dumps(rows))
    _report(rows, views, h1)
    print(f"total {time.perf_counter() - start:.0f} s", flush=True)


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
    session_s = time.perf_counter() - start
    print(f"session {final['state']}: {session_s:.0f} s here, {clock.now():.0f} s of rig "
          f"time, {sim.cameras.frames_exposed} frames exposed", flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
