"""Photometric stereo on each rig kind against the simulator's ray-cast truth (docs/photometric.md).

Run as ``python -m tests.integration.ps_kinds_table`` (~2 min): for the VirTex stage with
3 lamps (120° apart) and 6 lamps, and the Wang rig with 12 lamps, all at θ = 45°, a session
of the frontal view under every lamp through the daemon and the real drivers against the
simulated rig, then ``rig process --stages ps`` (robust solver), compared with
``Simulator.texel_truth`` on 128² texels. Prints one markdown row per run.
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

SIZE = 128
RUNS = (("virtex", 3), ("virtex", 6), ("wang", 12))


def ps_session(kind: str, lamps: int, effects: list[str], out: Path) -> dict:
    """Record and process one PS session of the bumps scene; its angular errors (deg)."""
    data = tomllib.loads(Path("examples/scenes/bumps.toml").read_text())
    data["render"] = {"scale": 0.5, "supersample": 2}
    data["effects"] = effects
    if kind == "virtex":
        data["rig"] = {"kind": "virtex", "overrides": {"virtex": {"lamp_count": lamps}}}
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
    assert final["state"] == "done", final
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


def main() -> None:
    out = Path(tempfile.mkdtemp(prefix="ps-kinds-"))
    for effects in ([], ["shadows", "noise"]):
        for kind, lamps in RUNS:
            t0 = time.time()
            row = ps_session(kind, lamps, effects, out / f"{kind}{lamps}{len(effects)}")
            print(
                f"| {kind} | {lamps} | {', '.join(effects) or 'none'} | {row['mean_deg']:.2f} | "
                f"{row['p95_deg']:.2f} | {row['valid']:.3f} | {row['session_s']:.1f} | "
                f"{time.time() - t0:.0f} |",
                flush=True,
            )


if __name__ == "__main__":
    main()
