"""Registration's time, this checkout against another, in one run (``docs/sim.md``).

Frames of the default scene (cameras 0, 2, 4, 6 at three turntable angles, two
lamps each) are rendered once; then each checkout registers them in its own
process, alternately, ``rounds`` times; each process times three passes over
the frames and keeps the fastest, and the median over the rounds of that CPU
time per frame is compared (CPU time: on a shared machine the wall clock
follows the load). This
checkout registers as ``register_capture`` does, with the markers expected
where the step's recorded turntable angle puts them; a checkout whose
``register_frame`` has no ``expected`` runs the detector. Both report the mean
reprojection error and the markers used, so equal accuracy is seen beside the time.

Run from the repository root::

    PYTHONPATH=. python -m tests.processing.registration.registration_speed /path/to/base

where ``/path/to/base`` is a checkout of the commit to compare with
(``git worktree add /tmp/base COMMIT --detach``).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

SCENE = "examples/scenes/default.toml"
SIZES = (64, 128, 256)

_TIMER = r"""
import inspect, json, sys, time
import numpy as np
from processing.registration import register_frame
from sim import load_scene

scene = load_scene(sys.argv[2])
holder = scene.rig.holder
with np.load(sys.argv[1]) as data:
    frames = {key: data[key] for key in data.files}
predicts = "expected" in inspect.signature(register_frame).parameters
out = {}
for size in json.loads(sys.argv[3]):
    def run():
        results = []
        for key, image in frames.items():
            camera_id, angle, _ = key.split("_")
            lens = scene.rig.camera_model(camera_id)
            options = {"camera": lens}
            if predicts:
                options["expected"] = scene.rig.camera_model(camera_id, turntable_deg=float(angle))
            results.append(register_frame(image, holder, size=size, **options))
        return results
    run()  # compiled kernels loaded, caches warm
    best = float("inf")
    for _ in range(3):  # the least disturbed of three passes
        start = time.process_time()
        results = run()
        best = min(best, time.process_time() - start)
    ms = best / len(frames) * 1e3
    out[size] = {
        "ms": ms, "valid": sum(r.valid for r in results),
        "markers": sum(len(r.homography.ids) for r in results),
        "reproj_px": float(np.mean([r.homography.mean_reprojection_px for r in results])),
    }
print(json.dumps(out))
"""


def render_frames(path: Path) -> None:
    """Write the frames to register (npz, keys ``cam_angle_lamp``)."""
    from sim import Simulator, load_scene

    frames = {}
    with Simulator(load_scene(SCENE)) as sim:
        for cam in ("cam0", "cam2", "cam4", "cam6"):
            for angle in (0, 40, 130):
                for lamp in ("lamp2", "lamp5"):
                    frame = sim.render_state(cam, turntable_deg=angle, lamps_on=[lamp])
                    frames[f"{cam}_{angle}_{lamp}"] = frame.image
    np.savez(path, **frames)


def measure(base: Path, *, rounds: int = 3, sizes=SIZES) -> list[dict]:
    """One row per texel size: median ms per frame of the base and of this checkout."""
    here = Path.cwd()
    runs: dict[str, list[dict]] = {"base": [], "this": []}
    with tempfile.TemporaryDirectory() as tmp:
        frames = Path(tmp) / "frames.npz"
        render_frames(frames)
        for _ in range(rounds):
            for name, root in (("base", base), ("this", here)):
                env = {**os.environ, "PYTHONPATH": str(root)}
                command = [sys.executable, "-c", _TIMER, str(frames), str(here / SCENE)]
                reply = subprocess.run(
                    [*command, json.dumps(sizes)],
                    cwd=root, env=env, capture_output=True, text=True, check=True,
                )  # fmt: skip
                runs[name].append(json.loads(reply.stdout.strip().splitlines()[-1]))
    rows = []
    for size in sizes:
        key = str(size)
        row = {"size": size}
        for name in runs:
            row[f"{name}_ms"] = float(np.median([r[key]["ms"] for r in runs[name]]))
            for field in ("valid", "markers", "reproj_px"):
                row[f"{name}_{field}"] = runs[name][-1][key][field]
        row["ratio"] = row["base_ms"] / row["this_ms"]
        rows.append(row)
    return rows


if __name__ == "__main__":
    print(
        "| texels | before ms | after ms | ratio | markers before / after "
        "| mean reproj. px before / after |"
    )
    print("|---|---|---|---|---|---|")
    for r in measure(Path(sys.argv[1]).resolve()):
        print(
            f"| {r['size']} | {r['base_ms']:.1f} | {r['this_ms']:.1f} | {r['ratio']:.1f}× | "
            f"{r['base_markers']} / {r['this_markers']} | "
            f"{r['base_reproj_px']:.4f} / {r['this_reproj_px']:.4f} |"
        )
