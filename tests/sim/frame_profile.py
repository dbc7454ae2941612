"""Where a simulated BTF frame's time goes, this checkout against another (``docs/sim.md``).

The default scene at one turntable angle, every camera × every lamp (64 frames, as
a Wang session visits a position), profiled with ``cProfile`` on CPU time in a
fresh process per checkout; the checkouts alternate for ``rounds`` rounds and the
medians are compared (CPU time: on a shared machine the wall clock follows the
load). Run from the repository root::

    PYTHONPATH=. python -m tests.sim.frame_profile /path/to/base

where ``/path/to/base`` is a checkout of the commit to compare with
(``git worktree add /tmp/base COMMIT --detach``).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

SCENE = "examples/scenes/default.toml"

# Stages: a label and the function (file suffix, name) whose cumulative time it is.
STAGES = [
    ("whole frame", ("sim/simulator.py", "render")),
    ("view: GL face ids + hit reconstruction (once per view)", ("sim/simulator.py", "_pixel_hits")),
    ("radiance: shadows, incidence, shading", ("sim/simulator.py", "_radiance")),
    ("of which shadow rays (`RayCaster.sees`)", ("sim/raycast.py", "sees")),
    ("shot + read noise (`add_noise`)", ("sim/sensor.py", "add_noise")),
    ("quantisation (`quantize`)", ("sim/sensor.py", "quantize")),
]

_PROFILER = r"""
import cProfile, json, pstats, sys, time
from sim import Simulator, load_scene

scene = load_scene(sys.argv[1])
stages = json.loads(sys.argv[2])
cameras = [c.id for c in scene.rig.camera_arc.cameras]
lamps = [lamp.id for lamp in scene.rig.light_arc.lamps]
with Simulator(scene) as sim:
    sim.render_state(cameras[0], turntable_deg=10.0, lamps_on=[lamps[0]])  # GL context, caches
    profile = cProfile.Profile(time.process_time)
    profile.enable()
    for camera in cameras:
        for lamp in lamps:
            sim.render_state(camera, turntable_deg=0.0, lamps_on=[lamp])
    profile.disable()
frames = len(cameras) * len(lamps)
found = {}
for (path, line, name), (_, _, _, cumulative, _) in pstats.Stats(profile).stats.items():
    for label, (suffix, function) in stages:
        if name == function and path.endswith(suffix):
            found[label] = found.get(label, 0.0) + cumulative / frames * 1e3
print(json.dumps(found))
"""


def measure(base: Path, *, rounds: int = 3) -> list[dict]:
    """Median CPU ms per frame of each stage in the base and in this checkout."""
    here = Path.cwd()
    runs: dict[str, list[dict]] = {"base": [], "this": []}
    for _ in range(rounds):
        for name, root in (("base", base), ("this", here)):
            reply = subprocess.run(
                [sys.executable, "-c", _PROFILER, str(here / SCENE), json.dumps(STAGES)],
                cwd=root, env={**os.environ, "PYTHONPATH": str(root)},
                capture_output=True, text=True, check=True,
            )  # fmt: skip
            runs[name].append(json.loads(reply.stdout.strip().splitlines()[-1]))
    rows = []
    for label, _ in STAGES:
        row = {"stage": label}
        for name in runs:
            row[f"{name}_ms"] = float(np.median([r.get(label, 0.0) for r in runs[name]]))
        rows.append(row)
    return rows


if __name__ == "__main__":
    rows = measure(Path(sys.argv[1]).resolve())
    whole = {name: rows[0][f"{name}_ms"] for name in ("base", "this")}
    print("| stage | before ms | share | after ms | share |")
    print("|---|---|---|---|---|")
    for r in rows:
        print(
            f"| {r['stage']} | {r['base_ms']:.1f} | {100 * r['base_ms'] / whole['base']:.0f} % | "
            f"{r['this_ms']:.1f} | {100 * r['this_ms'] / whole['this']:.0f} % |"
        )
    print(f"\nwhole frame: {whole['base'] / whole['this']:.2f}× (CPU time, medians)")
