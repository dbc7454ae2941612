"""The btfrig demo: a whole measurement session on the simulated rig, end to end.

Run by `make demo`. It plans and estimates a small session, runs it through the
daemon with the real device drivers talking to the simulated rig's peers (in
virtual time), replays it from the archive, writes PNGs of what the cameras
saw, processes the session on Dask (photometric stereo into normal, albedo
and height maps, the BTF into per-view PCA, the laser scans into the MDF), and
renders the measured material on a draped cloth. It uses only the public APIs
and says what it produced.
"""

from __future__ import annotations

import argparse
import shutil
import time
from pathlib import Path

import cv2
import numpy as np

from orchestrator.cli.plan_cmd import print_estimate
from orchestrator.cli.process_cmd import write_mdf_previews, write_ps_previews
from orchestrator.cli.view_scene import auto_exposure_ev, mesh_centre, parse_camera, parse_light
from orchestrator.local import replay_local, run_local
from processing.offline import BtfStage, MdfStage, PsStage, run_stages
from render import Renderer
from render.meshes import cloth
from render.output import write_png
from rig import compile_plan, load_plan
from rig.archive import Archive
from rig.clock import VirtualClock
from rig.material import read_material
from sim.rig import SimulatedRig

EXAMPLES = Path(__file__).parent
PLAN = EXAMPLES / "plans" / "demo.toml"
SCENE = EXAMPLES / "scenes" / "default.toml"
LIVE_STAGES = "stats,register,laser,ps"  # what the workers compute while capturing
# The final picture: a key light from the front left and a dimmer fill from the right.
RENDER_CAMERA = "orbit:60,-90"
RENDER_LIGHTS = ("dir:40,-130:1.0", "dir:60,-20:0.35")


def _progress(event: dict) -> None:
    if event.get("topic") == "progress" and event["step"] % 8 in (0, event["steps"] % 8):
        print(f"   step {event['step']:3d}/{event['steps']}  ({event['frames']} frames)")
    elif event.get("topic") == "state":
        print(f"   {event['from']} → {event['to']}")


def _to_8bit(image: np.ndarray) -> np.ndarray:
    if image.dtype == np.uint8:
        return image
    return (image.astype(np.float32) * (255.0 / np.iinfo(image.dtype).max)).astype(np.uint8)


def _contact_sheet(archive: Archive, kind: str, columns: int = 4) -> np.ndarray:
    """The frames of the first camera of every ``kind`` step, tiled (RGB, uint8)."""
    steps = [s for s in archive.step_table() if s.kind == kind]
    camera = steps[0].cameras[0]
    tiles = [_to_8bit(archive.read_frame(s.index, camera, 0)) for s in steps if camera in s.cameras]
    rows = -(-len(tiles) // columns)
    h, w = tiles[0].shape[:2]
    sheet = np.zeros((rows * h, columns * w, 3), np.uint8)
    for i, tile in enumerate(tiles):
        r, c = divmod(i, columns)
        sheet[r * h : (r + 1) * h, c * w : (c + 1) * w] = tile[..., :3]
    return sheet


def _render_cloth(archive_path: Path, out: Path) -> Path:
    """The session's material (its BTF, over the PS maps) on the draped cloth, at true scale."""
    material = read_material(archive_path)
    mesh = cloth()
    camera = parse_camera(RENDER_CAMERA).camera(mesh, (800, 600), fov_deg=30.0)
    lights = [parse_light(spec).light(mesh_centre(mesh)) for spec in RENDER_LIGHTS]
    with Renderer(material, mesh) as renderer:
        image = renderer.render(camera, lights)
    return write_png(out / "render_cloth.png", image, exposure_ev=auto_exposure_ev(image))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", type=Path, default=Path("out/demo"))
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    archive_path = args.out / "demo.zarr"
    replay_path = args.out / "demo.replay.zarr"
    for old in (archive_path, replay_path):
        if old.exists():
            shutil.rmtree(old)

    plan = load_plan(PLAN)
    clock = VirtualClock()
    t0 = time.perf_counter()
    with SimulatedRig(SCENE, clock=clock) as sim:
        config = sim.rig_config()
        print(f"1. plan {PLAN} is valid; on the simulated rig of scene {SCENE.name}:")
        print_estimate(compile_plan(plan, config))
        print(f"2. running the session through the daemon into {archive_path}")
        print(f"   two workers run the live stages {LIVE_STAGES} on every frame")
        final = run_local(
            PLAN, config, archive=archive_path, on_event=_progress, clock=clock,
            workers=2, stages=LIVE_STAGES,
        )  # fmt: skip
    if final["state"] != "done":
        print(f"   the session ended {final['state']}: {final['session'].get('reason')}")
        return 1
    s = final["session"]
    print(
        f"   {s['committed']} steps, {s['frames']} frames in {time.perf_counter() - t0:.0f} s "
        f"of wall time ({clock.now() / 60:.1f} min of rig time); "
        f"{final['stream']['processed']} processed live into material/live"
    )

    print(f"3. replaying it from the archive into {replay_path}")
    replayed = replay_local(archive_path, out=replay_path, speed=None)
    if replayed["state"] != "done":
        print(f"   the replay ended {replayed['state']}: {replayed['session'].get('reason')}")
        return 1
    with Archive.open(archive_path) as live, Archive.open(replay_path) as again:
        keys = [(int(r["step"]), str(r["camera"]), int(r["sub"])) for r in live.frame_table()]
        same = all(np.array_equal(live.read_frame(*k), again.read_frame(*k)) for k in keys)
        print(f"   {len(again.frame_table())} frames replayed, identical to the live ones: {same}")

        print("4. writing what the cameras saw")
        for kind in ("ps", "btf"):
            path = args.out / f"{kind}_frames.png"
            cv2.imwrite(str(path), cv2.cvtColor(_contact_sheet(live, kind), cv2.COLOR_RGB2BGR))
            print(f"   {path}")
    print("5. processing on Dask (rig process --stages ps,btf,mdf)")
    stages = [PsStage(size=128), BtfStage(size=128, components=8), MdfStage(size=128)]
    for run in run_stages(archive_path, stages):
        summary = ", ".join(f"{k} {v:.3g}" for k, v in run.summary.items())
        print(f"   {run.stage}: {run.items} item(s) → material/{run.stage} ({summary})")
    for path in [*write_ps_previews(archive_path, args.out),
                 *write_mdf_previews(archive_path, args.out)]:  # fmt: skip
        print(f"   {path}")
    print("6. rendering the measured material on a draped cloth (rig view --mesh cloth)")
    render_path = _render_cloth(archive_path, args.out)
    print(f"   {render_path}")
    size_mb = sum(f.stat().st_size for f in archive_path.rglob("*") if f.is_file()) / 1e6
    print(f"\nResults: {archive_path} ({size_mb:.1f} MB) and the PNGs in {args.out}")
    return 0 if same else 1


if __name__ == "__main__":
    raise SystemExit(main())
