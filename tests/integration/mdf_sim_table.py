"""MDF accuracy end to end against the simulator's ray-cast truth (docs/mdf.md table).

Run as ``python -m tests.integration.mdf_sim_table bumps default`` (~10 min): for each
scene, sessions through the daemon and the real drivers with 1, 5, 13 and 26 laser
locations at θ = 45° (frontal view, the rig's default scan step), then
``rig process --stages mdf``, compared with ``Simulator.mdf_truth`` on 128² texels.
Prints one markdown row per run.
"""

import sys
import tempfile
import time
import tomllib
from pathlib import Path

import numpy as np

from orchestrator.daemon import run_local
from processing.offline import MdfStage, run_stages
from rig.archive import Archive
from rig.clock import VirtualClock
from sim import Simulator
from sim.rig import SimulatedRig
from sim.scene import scene_from_dict

SIZE = 128


def main(scene_names: list[str]) -> None:
    out = Path(tempfile.mkdtemp(prefix="mdf-table-"))
    for scene_name in scene_names:
        data = tomllib.loads(Path(f"examples/scenes/{scene_name}.toml").read_text())
        if "laser" not in data.get("effects", []):
            data["effects"] = [*data.get("effects", []), "laser"]
            data["laser"] = {"power_w": 0.1}
        scene = scene_from_dict(data)
        with Simulator(scene) as sim:
            truth = sim.mdf_truth((0.0, 0.0), SIZE)
        for n in (1, 5, 13, 26):
            plan = out / f"plan{n}.toml"
            plan.write_text(
                f'[sample]\nname = "m{n}"\n[captures.mdf]\nviews = [[0, 0]]\n'
                f"laser_locations = {{theta_deg = 45, count = {n}}}\n"
            )
            archive = out / f"{scene_name}{n}.zarr"
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
            print(
                f"| {scene_name} | {n} | {np.median(err):.4f} | {np.percentile(err, 95):.3f} | "
                f"{np.median(err) / texel_mm:.4f} | {seen.sum() / visible.sum():.3f} | "
                f"{clock.now():.0f} | {t1 - t0:.0f} + {time.time() - t1:.0f} |",
                flush=True,
            )


if __name__ == "__main__":
    main(sys.argv[1:])
