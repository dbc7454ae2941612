"""MDF accuracy end to end against the simulator's ray-cast truth (docs/mdf.md tables).

``rig bench mdf-sim`` (~10 min): for each scene, sessions through the daemon and the real
drivers with 1, 5, 13 and 26 laser locations at θ = 45° (frontal view, the rig's default
scan step), then ``rig process --stages mdf``, compared with ``Simulator.mdf_truth`` on
128² texels. ``run(mounts=(45, 20))``: the rig has those laser mounts and the locations
are the ones ``rig sim coverage`` chooses (greedy to 99 %, and 5 even at the first mount +
greedy), beside the ray-cast prediction of their coverage. One row per session.
"""

from __future__ import annotations

import tempfile
import time
import tomllib
from pathlib import Path

import numpy as np

from orchestrator.local import run_local
from processing.offline import MdfStage, run_stages
from rig.archive import Archive
from rig.clock import VirtualClock
from sim import Simulator
from sim.coverage import coverage_rows
from sim.model import SceneModel
from sim.rig import SimulatedRig
from sim.scene import scene_from_dict
from studies import EXAMPLE_SCENES

__all__ = ["LOCATION_COUNTS", "SIZE", "run"]

SIZE = 128


#: laser locations per session, evenly spread in azimuth at θ = 45°
LOCATION_COUNTS = (1, 5, 13, 26)


def run(
    quick: bool = False,
    *,
    scenes: tuple[str, ...] | None = None,
    mounts: tuple[float, ...] | None = None,
) -> list[dict]:
    """One row per session: ``scene``, ``locations``, median and 95th-percentile height
    error (mm) over the texels both see, the median in texels, ``coverage`` (texels seen
    over the texels the camera truly sees), ``predicted`` (the ray-cast coverage of a
    chosen set), the rig time and the wall time of capture and processing.

    ``scenes``: example scenes by name (bumps and default; ``quick``: bumps with 1 and 5
    locations). ``mounts``: the rig's laser mounts (θ, degrees); the locations are then
    the ones ``rig sim coverage`` chooses (greedy to 99 %, and 5 even at the first mount
    + greedy).
    """
    scenes = scenes or (("bumps",) if quick else ("bumps", "default"))
    counts = LOCATION_COUNTS[:2] if quick else LOCATION_COUNTS
    rows = []
    with tempfile.TemporaryDirectory(prefix="rig-bench-mdf-sim-") as tmp:
        for scene_name in scenes:
            data = tomllib.loads((EXAMPLE_SCENES / f"{scene_name}.toml").read_text())
            if "laser" not in data.get("effects", []):
                data["effects"] = [*data.get("effects", []), "laser"]
                data["laser"] = {"power_w": 0.1}
            if mounts is None:
                runs = [(f"{n}", f"{{theta_deg = 45, count = {n}}}", None) for n in counts]
            else:
                data["rig"] = {"overrides": {"laser": {"mount_theta_deg": list(mounts)}}}
                runs = _chosen(scene_from_dict(data), list(mounts))
            scene = scene_from_dict(data)
            with Simulator(scene) as sim:
                truth = sim.mdf_truth((0.0, 0.0), SIZE)
            for i, (label, locations, predicted) in enumerate(runs):
                folder = Path(tmp) / f"{scene_name}{i}"
                row = _session(scene, locations, folder, truth)
                rows.append({"scene": scene_name, "locations": label, **row,
                             "predicted": predicted})  # fmt: skip
    return rows


def _session(scene, locations: str, folder: Path, truth: np.ndarray) -> dict:
    """Record and process one scan session; its errors against ``truth`` (N, N) mm."""
    folder.mkdir(parents=True)
    plan = folder / "plan.toml"
    plan.write_text(
        f'[sample]\nname = "mdf"\n[captures.mdf]\nviews = [[0, 0]]\nlaser_locations = {locations}\n'
    )
    archive = folder / "s.zarr"
    clock = VirtualClock()
    t0 = time.perf_counter()
    with SimulatedRig(scene, clock=clock) as rig:
        final = run_local(plan, rig.rig_config(), archive=archive, clock=clock)
    if final["state"] != "done":
        raise RuntimeError(f"the simulated scan session ended {final['state']}")
    t1 = time.perf_counter()
    run_stages(archive, [MdfStage(size=SIZE)])
    with Archive.open(archive) as recorded:
        distance = recorded.material["mdf"]["distance_mm"][0]
    visible = truth >= 0
    seen = (distance >= 0) & visible
    err = np.abs(distance[seen] - truth[seen])
    texel_mm = 100.0 / SIZE
    return {
        "median_mm": float(np.median(err)),
        "p95_mm": float(np.percentile(err, 95)),
        "median_texels": float(np.median(err)) / texel_mm,
        "coverage": float(seen.sum() / visible.sum()),
        "rig_s": clock.now(),
        "capture_wall_s": t1 - t0,
        "process_wall_s": time.perf_counter() - t1,
    }


def _chosen(scene, mounts: list[float]) -> list[tuple[str, str, float]]:
    """(label, laser_locations TOML, predicted coverage) of the chosen location sets."""
    rows = coverage_rows(SceneModel(scene), scene.rig, (0.0, 0.0), mounts=[mounts], n=SIZE)
    runs = []
    for row in rows:
        where = ", ".join(f"[{t:g}, {p:g}]" for t, p in np.round(row["locations"], 2))
        label = f"{len(row['locations'])}: {row['choice']}, mounts {mounts}"
        runs.append((label, f"[{where}]", row["coverage"]))
    return runs
