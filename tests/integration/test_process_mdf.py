"""`rig process --stages mdf` on laser scans recorded against the simulated rig, checked
against the simulator's ray-cast MDF (flat target 2 mm below the reference plane, frontal
view, one laser location at θ = 45°, the rig's default scan step of 0.133°): median
absolute error < 0.05 mm, 95th percentile < 0.3 mm, ≥ 95 % of the texels seen; the
sheet angle comes from the recorded tilt of every frame."""

from __future__ import annotations

import numpy as np
import pytest

from orchestrator.local import run_local
from processing.mdf import Reason
from processing.offline import MdfStage, run_stages
from rig.archive import Archive
from rig.clock import VirtualClock
from sim import Simulator
from sim.rig import SimulatedRig
from sim.scene import load_scene

# Sessions, subprocesses or benches: the full tier only (make test), not make quick.
pytestmark = pytest.mark.slow

SIZE = 48
PLAN = """
[sample]
name = "mdf"
[captures.mdf]
views = [[0, 0]]
laser_locations = [[45, 0]]
"""


@pytest.fixture(scope="module")
def scan(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("mdf")
    scene = load_scene("examples/scenes/flat_target.toml")
    (tmp / "plan.toml").write_text(PLAN)
    clock = VirtualClock()
    with SimulatedRig(scene, clock=clock) as sim:
        final = run_local(tmp / "plan.toml", sim.rig_config(), archive=tmp / "m.zarr", clock=clock)
    assert final["state"] == "done", final
    with Simulator(scene) as sim:
        truth = sim.mdf_truth((0.0, 0.0), SIZE)
    return tmp / "m.zarr", truth


def test_mdf_matches_the_ray_cast_truth(scan):
    archive, truth = scan
    (run,) = run_stages(archive, [MdfStage(size=SIZE)])
    assert run.items == 1
    with Archive.open(archive) as arch:
        group = arch.material["mdf"]
        distance, reason = group["distance_mm"][0], group["reason"][0]
        assert group.attrs["unseen"] == -1.0
    assert np.isfinite(distance).all()
    visible = truth >= 0
    seen = (distance >= 0) & visible
    assert seen.sum() >= 0.95 * visible.sum()
    assert np.all((distance >= 0) == (reason <= Reason.EDGE))  # -1 exactly where flagged
    error = np.abs(distance[seen] - truth[seen])
    assert np.median(error) < 0.05 and np.percentile(error, 95) < 0.3, (
        np.median(error), np.percentile(error, 95),
    )  # fmt: skip


def test_frames_still_flagged_are_left_out_of_the_mdf(scan, tmp_path):
    """The same scan with the middle third of its frames flagged as never matching their
    tilt: the stage leaves them out, so the texels only they swept go unseen, and the
    rest is as before."""
    from dataclasses import replace

    from rig.archive import FrameFlag, FrameRecord

    archive, _ = scan
    copy = tmp_path / "flagged.zarr"
    with Archive.open(archive) as source:
        (record,) = source.step_table()
        (event,) = source.events("scan")
        n = len(event.payload["tilts_deg"])
        middle = range(n // 3, 2 * n // 3)
        flags = tuple(FrameFlag("cam0", sub, "laser tilt read back off", False) for sub in middle)
        rows = source.frame_table()
        with Archive.create(copy, plan=source.plan, rig_config=source.rig_config,
                            cameras=source.cameras, fsync=False) as target:  # fmt: skip
            target.log_event("scan", **event.payload)
            frames = [FrameRecord(source.read_frame(record.index, "cam0", int(r["sub"])),
                                  int(r["sub"]), float(r["exposure_s"]), float(r["timestamp"]))
                      for r in rows]  # fmt: skip
            target.append_step(replace(record, flags=flags, committed_at=None), {"cam0": frames})
    seen = {}
    for path in (archive, copy):
        run_stages(path, [MdfStage(size=SIZE)])
        with Archive.open(path) as arch:
            seen[path] = arch.material["mdf"]["distance_mm"][0] >= 0
    assert record.cameras == ("cam0",)
    kept, full = seen[copy].sum(), seen[archive].sum()
    assert 0.2 * full < kept < 0.8 * full  # a third of the sweep's frames missing
    assert not np.any(seen[copy] & ~seen[archive])  # nothing seen that was not before
