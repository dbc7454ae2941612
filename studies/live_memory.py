"""Peak memory of a session with a ``register`` worker, by session length (tracemalloc).

Daemon, one worker and soft devices in one process, on virtual time; the peak
of Python allocations over the whole session. Run from the repository root::

    python -m tests.orchestrator.daemon.live_memory 500 1000 2000
"""

from __future__ import annotations

import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

from orchestrator.local import run_local
from rig.clock import VirtualClock
from rig.config import default_rig_config
from tests.orchestrator.daemon.soft import SoftRig, soft_devices

#: 4 cameras × 2 exposures = 8 frames per lamp; the lamp count sets the length.
PLAN = """
[sample]
name = "memory"
[captures.btf]
views = [[0, 0], [30, 0], [45, 0], [60, 0]]
lights = {{theta_deg = 45, count = {lamps}}}
[exposure]
hdr_brackets = [1.0, 2.0]
[resolution]
scale = 0.0625
"""


def session_peak(frames: int, root: Path) -> dict:
    """Run a session of ``frames`` frames (a multiple of 8); its peak memory and counts."""
    plan = root / f"plan-{frames}.toml"
    plan.write_text(PLAN.format(lamps=frames // 8))
    rig = SoftRig(default_rig_config(), VirtualClock())
    tracemalloc.start()
    wall = time.perf_counter()
    try:
        final = run_local(
            plan, None, archive=root / f"s-{frames}.zarr", workers=1, stages="register",
            devices=soft_devices(rig), clock=rig.clock,
        )  # fmt: skip
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    return {
        "frames": final["session"]["frames"],
        "processed": final["stream"]["processed"],
        "peak_mb": peak / 1e6,
        "wall_s": time.perf_counter() - wall,
    }


if __name__ == "__main__":
    with tempfile.TemporaryDirectory() as tmp:
        for n in map(int, sys.argv[1:]):
            row = session_peak(n, Path(tmp))
            print(" | ".join(f"{k} {v:.1f}" if isinstance(v, float) else f"{k} {v}"
                             for k, v in row.items()), flush=True)  # fmt: skip
