"""Photometric stereo on each rig kind against the simulator's ray-cast truth (docs/photometric.md).

``rig bench ps-kinds`` (~2 min): for the VirTex stage with 3 lamps (120° apart) and 6
lamps, and the Wang rig with 12 lamps, all at θ = 45°, a session of the frontal view under
every lamp through the daemon and the real drivers against the simulated rig, then ``rig
process --stages ps`` (robust solver), compared with ``Simulator.texel_truth`` on 128²
texels; without effects and with shadows and noise. One row per run.
"""

from __future__ import annotations

import tempfile
import time
import tomllib
from pathlib import Path

import numpy as np

from orchestrator.local import run_local
from processing.offline import PsStage, run_stages
from rig.clock import VirtualClock
from rig.material import read_material
from sim import Simulator
from sim.rig import SimulatedRig
from sim.scene import scene_from_dict
from studies import EXAMPLE_SCENES

__all__ = ["RUNS", "SIZE", "ps_session", "run"]

SIZE = 128
#: (rig kind, lamps) of each session
RUNS = (("virtex", 3), ("virtex", 6), ("wang", 12))
#: the runs of ``quick``: the VirTex stage's, the cheapest sessions
QUICK_RUNS = RUNS[:2]
#: the simulator's effects of each set of sessions
EFFECTS = ((), ("shadows", "noise"))


def ps_session(kind: str, lamps: int, effects, out: Path) -> dict:
    """Record and process one PS session of the bumps scene; its angular errors (deg)."""
    data = tomllib.loads((EXAMPLE_SCENES / "bumps.toml").read_text())
    data["render"] = {"scale": 0.5, "supersample": 2}
    data["effects"] = list(effects)
    # the VirTex stage's lamps are its own; the Wang rig's set comes from the plan
    overrides = {"virtex": {"virtex": {"lamp_count": lamps}}}.get(kind, {})
    data["rig"] = {"kind": kind, "overrides": overrides}
    scene = scene_from_dict(data)
    with Simulator(scene) as sim:
        truth = sim.texel_truth(SIZE)
    out.mkdir(parents=True, exist_ok=True)
    plan = out / "plan.toml"
    plan.write_text(
        f'[sample]\nname = "ps"\n[captures.ps]\nviews = [[0, 0]]\n'
        f"lights = {{theta_deg = 45, count = {lamps}}}\n[exposure]\nexposure_s = 0.05\n"
    )
    archive = out / "ps.zarr"
    clock = VirtualClock()
    with SimulatedRig(scene, clock=clock) as rig:
        final = run_local(plan, rig.rig_config(), archive=archive, clock=clock)
    if final["state"] != "done":
        raise RuntimeError(f"the simulated {kind} session ended {final['state']}")
    run_stages(archive, [PsStage(size=SIZE)])
    (view,) = read_material(archive).ps.values()
    cos = np.clip(np.sum(view.normals * truth.normals, axis=-1), -1.0, 1.0)
    err = np.degrees(np.arccos(cos))[view.valid]
    return {
        "archive": archive,
        "mean_deg": float(err.mean()),
        "p95_deg": float(np.percentile(err, 95)),
        "valid": float(view.valid.mean()),
        "session_s": clock.now(),
    }


def run(quick: bool = False) -> list[dict]:
    """One row per session: ``rig`` (its kind), ``lamps``, ``effects``, mean and 95th-percentile
    angular error (degrees), the valid fraction, the session's rig time and the wall time
    of session and processing. ``quick``: the VirTex sessions without effects."""
    runs = [(kind, lamps, ()) for kind, lamps in QUICK_RUNS] if quick else [
        (kind, lamps, effects) for effects in EFFECTS for kind, lamps in RUNS
    ]  # fmt: skip
    rows = []
    with tempfile.TemporaryDirectory(prefix="rig-bench-ps-kinds-") as tmp:
        for i, (kind, lamps, effects) in enumerate(runs):
            wall = time.perf_counter()
            row = ps_session(kind, lamps, effects, Path(tmp) / f"{i}")
            rows.append({
                "rig": kind, "lamps": lamps, "effects": ", ".join(effects) or "none",
                "mean_deg": row["mean_deg"], "p95_deg": row["p95_deg"], "valid": row["valid"],
                "session_s": row["session_s"], "wall_s": time.perf_counter() - wall,
            })  # fmt: skip
    return rows
