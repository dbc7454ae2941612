"""How much the daemon itself costs: overhead per step and frames/s through the pipeline.

A session runs through the real daemon, sockets, archive and stats workers,
against ``ModelledRig``: a harness that spends exactly the modelled
hardware time (moves, settle, lamp warm-up, exposure + readout: the
:mod:`rig.timing` model that ``rig.schedule.estimate`` uses) on a
``VirtualClock`` and hands out constant frames. Everything the wall clock then
measures is the daemon's own work: step sequencing, commits (zstd + journal),
events, streaming. The overhead is reported as a fraction of the modelled
session time (goal: under 2 %).
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

from orchestrator import client
from orchestrator.daemon.devices import Captured
from orchestrator.daemon.session import frame_formats
from orchestrator.local import daemon_thread, worker_threads
from orchestrator.wire.endpoints import DaemonSettings
from rig.archive import FrameFormat
from rig.clock import VirtualClock
from rig.config import RigConfig, default_rig_config
from rig.plan import load_plan
from rig.schedule import compile_plan
from rig.timing import motion_s, shots_s

__all__ = ["ModelledRig", "modelled_devices", "run"]

_PLAN = """
[sample]
name = "bench"
[captures.btf]
views = {views}
lights = {{theta_deg = 45, count = {lights}}}
[exposure]
hdr_brackets = [1.0, 4.0]
[resolution]
scale = {scale}
"""


class ModelledRig:
    """The hardware's modelled time on a virtual clock, constant frames (studies only)."""

    def __init__(self, config: RigConfig, *, clock: VirtualClock, scale: float, laser: bool):
        self.config, self.clock, self.scale = config, clock, scale
        self.formats: dict[str, FrameFormat] = frame_formats(config, scale=scale)
        self.images = {c: np.full(f.shape, 100, dtype=f.dtype) for c, f in self.formats.items()}
        self.here = (config.turntable.axis.min_deg, config.light_arc.axis.min_deg)

    def home(self, *, laser: bool) -> None:
        self.here = (0.0, 0.0)

    def place(self, pose) -> dict[str, float]:
        return self.move(turntable_deg=pose.turntable_deg, arc_deg=pose.arc_deg)

    def move(self, *, turntable_deg: float, arc_deg: float) -> dict[str, float]:
        move, settle = motion_s(self.config, self.here, (turntable_deg, arc_deg))
        self.clock.sleep(float(move + settle))
        self.here = (turntable_deg, arc_deg)
        return {"turntable_deg": turntable_deg, "arc_deg": arc_deg}

    def forget_position(self) -> None:
        pass

    def lamp(self, lamp_id: str, on: bool) -> None:
        self.clock.sleep(self.config.lamp_bank.warmup_s)  # the bank waits on and off

    def laser(self, mount: int, on: bool) -> None:
        pass

    def capture(self, cameras, exposures_s) -> dict[str, list[Captured]]:
        frames = {c: [] for c in cameras}
        for sub, exposure in enumerate(exposures_s):
            self.clock.sleep(shots_s(self.config, cameras, [exposure], scale=self.scale))
            for c in cameras:
                frames[c].append(Captured(self.images[c], sub, exposure, self.clock.now()))
        return frames

    def scan(self, cameras, *, tilt_deg, frames, exposure_s):
        raise NotImplementedError("the bench plan has no laser scans")

    def all_off(self) -> None:
        pass

    def telemetry(self) -> dict:
        return {}

    def close(self) -> None:
        pass


def modelled_devices(config: RigConfig, *, clock: VirtualClock, scale: float, laser: bool):
    """A device factory of the daemon (``DeviceFactory``): a :class:`ModelledRig`."""
    return ModelledRig(config, clock=clock, scale=scale, laser=laser)


def _session(plan_text: str, *, workers: int, root: Path) -> dict:
    config = default_rig_config()
    clock = VirtualClock()
    plan = root / "plan.toml"
    plan.write_text(plan_text)

    settings = DaemonSettings(port=0, status_interval_s=0.5, drain_timeout_s=60.0)
    daemon = daemon_thread(config, settings=settings, devices=modelled_devices, clock=clock)
    with daemon as endpoints, worker_threads(endpoints, "stats", workers):
        deadline = time.monotonic() + 10
        while workers and client.status(connect=endpoints)["workers"] < workers:
            if time.monotonic() > deadline:
                raise TimeoutError("the bench workers did not connect")
            time.sleep(0.01)
        wall0 = time.perf_counter()
        client.submit(plan, archive=root / f"bench-{workers}.zarr", connect=endpoints)
        final = client.wait_for_state(endpoints, ("done",), settled=True, timeout_s=600)
        wall = time.perf_counter() - wall0
    session = final["session"]
    return {
        "workers": workers,
        "steps": session["steps"],
        "frames": session["frames"],
        "processed": final["stream"]["processed"],
        "modelled_s": clock.now(),
        "estimate_s": compile_plan(load_plan(plan), config).estimate.total_s,
        "wall_s": wall,
        "overhead_per_step_ms": 1e3 * wall / session["steps"],
        "overhead_fraction": wall / clock.now(),
        "frames_per_s": session["frames"] / wall,
    }


def run(quick: bool = False) -> list[dict]:
    """Rows: per session size and worker count, the daemon's overhead and throughput.

    ``overhead_fraction`` = wall time of the session / modelled hardware time
    (the wall time is all daemon: the modelled rig only advances a virtual
    clock); ``modelled_s`` equals ``estimate_s``, the plan's estimate, when the
    daemon runs the steps as planned. ``frames_per_s`` counts frames captured,
    committed and streamed per wall second (with workers: also processed before
    the session ends).
    """
    sizes = [("[[0, 0], [30, 0]]", 8, 0.125)] if quick else [
        ("[[0, 0], [30, 0], [30, 90], [45, 180]]", 12, 0.125),
        ("[[0, 0], [30, 0], [30, 90], [45, 180]]", 12, 0.5),
    ]  # fmt: skip
    rows = []
    with tempfile.TemporaryDirectory(prefix="rig-daemon-bench-") as tmp:
        for i, (views, lights, scale) in enumerate(sizes):
            text = _PLAN.format(views=views, lights=lights, scale=scale)
            for workers in (0, 2):
                root = Path(tmp) / f"{i}-{workers}"
                root.mkdir()
                row = _session(text, workers=workers, root=root)
                rows.append({"scale": scale, **row})
    return rows
