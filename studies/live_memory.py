"""Peak memory of a session with a ``register`` worker, by session length (tracemalloc).

Daemon, one worker and the modelled rig of :mod:`studies.daemon_overhead` (its hardware
time on a virtual clock, constant frames) in one process; the peak of Python allocations
over the whole session (docs/daemon.md, ``rig bench live-memory``).
"""

from __future__ import annotations

import tempfile
import time
import tracemalloc
from pathlib import Path

from orchestrator.local import run_local
from rig.clock import VirtualClock
from rig.config import default_rig_config
from studies.daemon_overhead import modelled_devices

__all__ = ["FRAMES", "QUICK_FRAMES", "run", "session_peak"]

#: session lengths in frames (``--quick``: 200 and 1000)
FRAMES = (200, 496, 1000, 2000)
QUICK_FRAMES = (200, 1000)

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
    clock = VirtualClock()
    tracemalloc.start()
    wall = time.perf_counter()
    try:
        final = run_local(
            plan, default_rig_config(), archive=root / f"s-{frames}.zarr", workers=1,
            stages="register", devices=modelled_devices, clock=clock,
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


def run(quick: bool = False) -> list[dict]:
    """One row per session length (:data:`FRAMES`): frames captured and processed, the
    peak of Python allocations (MB) and the wall time."""
    with tempfile.TemporaryDirectory(prefix="rig-bench-live-memory-") as tmp:
        return [session_peak(n, Path(tmp)) for n in (QUICK_FRAMES if quick else FRAMES)]
