"""``rig bench process``: how ``rig process`` scales with Dask workers and ``--size``.

A session of photometric-stereo views is recorded on the simulated rig in
virtual time (``run_local``; the examples' bumps sample), then the ``ps`` stage
runs over it through ``processing.offline.run_stages`` as ``rig process
--stages ps --size S`` runs it: with ``--workers N`` (the local cluster of N
threads, the default) and with ``--scheduler`` pointing at a local cluster of N
single-threaded worker processes (each item opens the archive itself in both).
Rows per cluster kind, size and worker count: items per second and the speed-up
against one worker of the same kind at the same size, in the same run.

Where the time goes, per row: ``cpu_s_per_item`` is the CPU time of the thread
computing an item, per item (the work itself, whatever the machine's load);
``compute_share`` is the fraction of the workers' wall time spent inside the
stage's ``compute`` (the rest: starting the cluster, scheduling, gathering
results, writing ``material/ps``); ``cpu_per_compute`` is CPU seconds per wall
second inside ``compute``: below 1 the items wait, for the GIL or for cores that
other threads and programs hold.

It records with the simulator and processes with the offline stages, so it
lives on top of both.
"""

from __future__ import annotations

import contextlib
import logging
import os
import tempfile
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from orchestrator.local import run_local
from processing.offline import PsStage, Stage, run_stages
from rig.archive import Archive
from rig.clock import VirtualClock
from rig.errors import RigError
from rig.material import read_material
from sim.rig import SimulatedRig
from sim.scene import scene_from_dict
from studies.render_loop import SCENES, patient_cameras

__all__ = ["record_session", "run"]


def record_session(folder: Path, *, views: int, lamps: int) -> Path:
    """A ``ps`` session of ``views`` views (θ = 30°, φ spread over the turn) × ``lamps``
    lamps at θ = 45°, recorded on the simulated rig; its archive."""
    directions = ", ".join(f"[30, {360.0 * v / views:g}]" for v in range(views))
    plan_path, archive = folder / "plan.toml", folder / "session.zarr"
    plan_path.write_text(
        f'[sample]\nname = "scaling"\n[captures.ps]\nviews = [{directions}]\n'
        f"lights = {{theta_deg = 45, count = {lamps}}}\n[exposure]\nexposure_s = 0.05\n"
    )
    clock = VirtualClock()
    with SimulatedRig(scene_from_dict(SCENES["bumps"]), clock=clock) as rig:
        config = patient_cameras(rig.rig_config())
        final = run_local(plan_path, config, archive=archive, clock=clock, on_fault="fail")
    if final.get("state") != "done":
        raise RigError(f"the simulated session of {plan_path} ended {final.get('state')}")
    return archive


@dataclass(frozen=True)
class _Timed:
    """A stage whose items also report their wall and CPU seconds inside ``compute``;
    ``write`` adds them to the stage's summary."""

    stage: Stage

    @property
    def name(self) -> str:
        return self.stage.name

    def plan(self, archive: Archive) -> list[Any]:
        return self.stage.plan(archive)

    def compute(self, archive_path: str, item: Any) -> tuple[Any, float, float]:
        wall, cpu = time.perf_counter(), time.thread_time()
        result = self.stage.compute(archive_path, item)
        return result, time.perf_counter() - wall, time.thread_time() - cpu

    def write(self, group, archive: Archive, results) -> dict:
        summary = self.stage.write(group, archive, [r[0] for r in results])
        return {
            **summary,
            "compute_s": sum(r[1] for r in results),
            "compute_cpu_s": sum(r[2] for r in results),
        }


#: How the workers run: ``rig process``'s own local cluster of ``--workers`` threads,
#: or a running cluster of single-threaded worker processes given as ``--scheduler``.
CLUSTERS = ("threads", "processes")


@contextlib.contextmanager
def _cluster(kind: str, workers: int) -> Iterator[dict]:
    """``run_stages``' options for ``workers`` workers of ``kind``."""
    if kind == "threads":
        yield {"workers": workers}
        return
    from distributed import LocalCluster

    with LocalCluster(
        n_workers=workers, threads_per_worker=1, processes=True,
        dashboard_address="127.0.0.1:0", silence_logs=logging.ERROR,
    ) as cluster:  # fmt: skip
        yield {"scheduler": cluster.scheduler_address}


def _run(archive: Path, *, size: int, workers: int, options: dict) -> dict:
    wall = time.perf_counter()
    (stage_run,) = run_stages(archive, [_Timed(PsStage(size=size))], **options)
    wall = time.perf_counter() - wall
    compute_s = stage_run.summary["compute_s"]
    return {
        "size": size,
        "workers": workers,
        "items": stage_run.items,
        "written": len(read_material(archive).ps),
        "wall_s": wall,
        "items_per_s": stage_run.items / wall,
        "cpu_s_per_item": stage_run.summary["compute_cpu_s"] / stage_run.items,
        "compute_share": compute_s / (workers * wall),
        "cpu_per_compute": stage_run.summary["compute_cpu_s"] / compute_s,
    }


def run(
    quick: bool = False,
    *,
    sizes: tuple[int, ...] | None = None,
    workers: tuple[int, ...] | None = None,
    clusters: tuple[str, ...] = CLUSTERS,
    views: int | None = None,
    lamps: int = 6,
    repeats: int | None = None,
) -> list[dict]:
    """Rows per cluster kind (:data:`CLUSTERS`), ``--size`` and worker count (1, 2 and
    all cores by default): items (views) per second of ``rig process --stages ps``,
    and ``speedup``: items/s against the fewest workers (one by default) of the same
    kind at the same size, in the same run (best of ``repeats``).

    ``views``: the session's views, the stage's items (default twice the most
    workers, at least 8, so every worker has items to take); ``written``: the views
    found in ``material/ps`` afterwards. An untimed run first imports and warms what
    the stage uses (in each cluster of processes).
    """
    unknown = set(clusters) - set(CLUSTERS)
    if unknown:
        raise ValueError(f"clusters {sorted(unknown)}: valid are {CLUSTERS}")
    cores = os.cpu_count() or 1
    sizes = sizes or ((32, 64) if quick else (64, 128, 256))
    workers = tuple(sorted(set(workers or (1, 2, cores))))
    views = views or (4 if quick else max(8, 2 * max(workers)))
    repeats = repeats or (1 if quick else 2)
    rows = []
    with tempfile.TemporaryDirectory(prefix="rig-process-bench-") as tmp:
        archive = record_session(Path(tmp), views=views, lamps=lamps)
        _run(archive, size=min(sizes), workers=1, options={"workers": 1})
        for kind in clusters:
            for count in workers:
                with _cluster(kind, count) as options:
                    if kind != "threads":
                        _run(archive, size=min(sizes), workers=count, options=options)
                    for size in sizes:
                        runs = [
                            _run(archive, size=size, workers=count, options=options)
                            for _ in range(repeats)
                        ]
                        best = max(runs, key=lambda r: r["items_per_s"])
                        rows.append({"cluster": kind, **best})
    for row in rows:  # the fewest workers come first
        base = next(r for r in rows if (r["cluster"], r["size"]) == (row["cluster"], row["size"]))
        row["speedup"] = row["items_per_s"] / base["items_per_s"]
        row["cores"] = cores
    return sorted(rows, key=lambda r: (clusters.index(r["cluster"]), r["size"], r["workers"]))
