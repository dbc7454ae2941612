"""MDF accuracy end to end against the simulator's ray-cast truth (docs/mdf.md tables).

Run as ``python -m tests.integration.mdf_sim_table bumps default`` (~10 min): for each
scene, sessions through the daemon and the real drivers with 1, 5, 13 and 26 laser
locations at θ = 45° (frontal view, the rig's default scan step), then
``rig process --stages mdf``, compared with ``Simulator.mdf_truth`` on 128² texels.
With ``--mounts 45,20`` the rig has those laser mounts and the locations are the ones
``rig sim coverage`` chooses (greedy to 99 %, and 5 even at the first mount + greedy),
beside the ray-cast prediction of their coverage. Prints one markdown row per run.
"""

import sys
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

SIZE = 128


def main(args: list[str]) -> None:
    mounts = None
    if "--mounts" in args:
        at = args.index("--mounts")
        mounts = [float(m) for m in args[at + 1].split(",")]
        args = args[:at] + args[at + 2 :]
    out = Path(tempfile.mkdtemp(prefix="mdf-table-"))
    for scene_name in args:
        data = tomllib.loads(Path(f"examples/scenes/{scene_name}.toml").read_text())
        if "laser" not in data.get("effects", []):
            data["effects"] = [*data.get("effects", []), "laser"]
            data["laser"] = {"power_w": 0.1}
        if mounts is None:
            runs = [(f"{n}", f"{{theta_deg = 45, count = {n}}}", None) for n in (1, 5, 13, 26)]
        else:
            data["rig"] = {"overrides": {"laser": {"mount_theta_deg": mounts}}}
            runs = _chosen(scene_from_dict(data), mounts)
        scene = scene_from_dict(data)
        with Simulator(scene) as sim:
            truth = sim.mdf_truth((0.0, 0.0), SIZE)
        for i, (label, locations, predicted) in enumerate(runs):
            plan = out / f"plan{i}.toml"
            plan.write_text(
                f'[sample]\nname = "m{i}"\n[captures.mdf]\nviews = [[0, 0]]\n'
                f"laser_locations = {locations}\n"
            )
            archive = out / f"{scene_name}{i}.zarr"
            clock = VirtualClock()
            t0 = time.time()
            with SimulatedRig(scene, clock=clock) as rig:
                final = run_local(plan, rig.rig_config(), archive=archive, clock=clock)
            assert final["state"] == "done", final
            t1 = time.time()
            run_stages(archive, [MdfStage(size=SIZE)])
            with Archive.open(archive) as a:
                d = a.material["mdf"]["distance_mm"][0]
            visible = truth >= 0
            seen = (d >= 0) & visible
            err = np.abs(d[seen] - truth[seen])
            texel_mm = 100.0 / SIZE
            expected = "" if predicted is None else f" (ray cast {predicted:.3f})"
            print(
                f"| {scene_name} | {label} | {np.median(err):.4f} | {np.percentile(err, 95):.3f} | "
                f"{np.median(err) / texel_mm:.4f} | {seen.sum() / visible.sum():.3f}{expected} | "
                f"{clock.now():.0f} | {t1 - t0:.0f} + {time.time() - t1:.0f} |",
                flush=True,
            )


def _chosen(scene, mounts: list[float]) -> list[tuple[str, str, float]]:
    """(label, laser_locations TOML, predicted coverage) of the chosen location sets."""
    rows = coverage_rows(SceneModel(scene), scene.rig, (0.0, 0.0), mounts=[mounts], n=SIZE)
    runs = []
    for row in rows:
        where = ", ".join(f"[{t:g}, {p:g}]" for t, p in np.round(row["locations"], 2))
        label = f"{len(row['locations'])}: {row['choice']}, mounts {mounts}"
        runs.append((label, f"[{where}]", row["coverage"]))
    return runs


if __name__ == "__main__":
    main(sys.argv[1:])
