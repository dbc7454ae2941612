"""A full H1 BTF session on the simulated Bonn lab, through the daemon and the real drivers
(UR arm, rail, lamp bank, camera) against the lab's peers: every (view, light) pair of H1
captured exactly once, every frame registered (docs/btf.md).

Run as ``python -m tests.integration.bonn_h1 [--views N] OUT_DIR``: ``--views`` keeps the
first N of H1's views (all 81 lights each) for a shorter run.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from orchestrator.daemon import run_local
from processing.registration import register_frame
from rig import bonn
from rig.archive import Archive
from rig.clock import VirtualClock
from rig.geometry import Sampling, angular_distance_deg, direction_vector
from rig.ur_kinematics import Pose
from sim.rig import SimulatedRig
from tests.sim.bonn_registration import bonn_scene


def _plan(views: list[tuple[float, float]]) -> str:
    listed = ", ".join(f"[{t}, {p}]" for t, p in views)
    return (
        f'[sample]\nname = "h1"\n[captures.btf]\nviews = [{listed}]\nlights = "H1"\n'
        "[exposure]\nexposure_s = 0.05\n"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("--views", type=int, default=81)
    parser.add_argument("--supersample", type=int, default=3, help="area samples per pixel side")
    args = parser.parse_args()
    h1 = [tuple(map(float, d)) for d in Sampling.named("H1").directions]
    views = h1[: args.views]
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "plan.toml").write_text(_plan(views))
    clock = VirtualClock()
    start = time.perf_counter()
    scene = bonn_scene(supersample=args.supersample)
    with SimulatedRig(scene, clock=clock) as sim:
        config = sim.rig_config()
        final = run_local(args.out / "plan.toml", config, archive=args.out / "s.zarr", clock=clock)
        rig = sim.scene.rig
    session_s = time.perf_counter() - start
    print(f"session {final['state']}: {session_s:.0f} s here, {clock.now():.0f} s of rig time")
    with Archive.open(args.out / "s.zarr") as archive:
        steps = archive.step_table()
        seen, reprojection, invalid = set(), [], 0
        for step in steps:
            view, light = step.views_deg["cam0"], step.light_deg
            v = min(range(len(views)), key=lambda i: angular_distance_deg(
                direction_vector(*views[i]), direction_vector(*view)))  # fmt: skip
            lt = min(range(len(h1)), key=lambda i: angular_distance_deg(
                direction_vector(*h1[i]), direction_vector(*light)))  # fmt: skip
            seen.add((v, lt))
            a = step.actuators
            tool = Pose((0.0, 0.0, 0.0), tuple(np.radians([a[f"tool_r{c}_deg"] for c in "xyz"])))
            camera = bonn.camera_model(rig, "cam0", tool.matrix()[:3, :3], a["rail_deg"])
            result = register_frame(archive.read_frame(step.index, "cam0", 0), rig.holder,
                                    size=64, camera=camera)  # fmt: skip
            if result.valid:
                reprojection.append(result.homography.mean_reprojection_px)
            else:
                invalid += 1
    wanted = len(views) * len(h1)
    print(f"steps {len(steps)}, distinct pairs {len(seen)} of {wanted}, "
          f"registered {len(reprojection)}, not registered {invalid}")  # fmt: skip
    r = np.asarray(reprojection)
    print(f"mean marker reprojection {r.mean():.3f} px (p95 {np.percentile(r, 95):.3f}, "
          f"max {r.max():.3f}); total {time.perf_counter() - start:.0f} s")  # fmt: skip


if __name__ == "__main__":
    main()
