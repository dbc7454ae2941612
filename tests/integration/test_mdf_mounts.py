"""A second, steeper laser mount end to end: the daemon lights mount 1's diode on
the NXT brick's third output, the simulator renders that mount's sheet, and
`rig process --stages mdf` reconstructs the flat target (2 mm below the
reference plane) from it against the ray-cast truth.

A 20° sheet moves 2.7 × less across the surface per mm of depth than a 45°
one, so the bound is looser than the 45° test's (test_process_mdf.py)."""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest

from orchestrator.local import run_local
from processing.offline import MdfStage, run_stages
from rig.archive import Archive
from rig.clock import VirtualClock
from sim import Simulator
from sim.rig import SimulatedRig
from sim.scene import scene_from_dict

# Sessions, subprocesses or benches: the full tier only (make test), not make quick.
pytestmark = pytest.mark.slow

SIZE = 48
PLAN = """
[sample]
name = "mounts"
[captures.mdf]
views = [[0, 0]]
laser_locations = [[20, 0]]
"""


def test_a_steep_second_mount_scans_the_flat_target(tmp_path):
    path = Path("examples/scenes/flat_target.toml")
    data = tomllib.loads(path.read_text())
    data["rig"] = {"overrides": {"laser": {"mount_theta_deg": [45.0, 20.0]}}}
    scene = scene_from_dict(data, source=str(path), base_dir=path.parent)
    (tmp_path / "plan.toml").write_text(PLAN)
    clock = VirtualClock()
    archive = tmp_path / "m.zarr"
    with SimulatedRig(scene, clock=clock) as sim:
        final = run_local(tmp_path / "plan.toml", sim.rig_config(), archive=archive, clock=clock)
    assert final["state"] == "done", final
    with Simulator(scene) as sim:
        truth = sim.mdf_truth((0.0, 0.0), SIZE)
    run_stages(archive, [MdfStage(size=SIZE)])
    with Archive.open(archive) as arch:
        assert [record.laser for record in arch.step_table()] == [1]
        distance = arch.material["mdf"]["distance_mm"][0]
    visible = truth >= 0
    seen = (distance >= 0) & visible
    assert seen.sum() >= 0.95 * visible.sum()
    error = np.abs(distance[seen] - truth[seen])
    # measured: median 0.101 mm, p95 0.37 (0.09 before the recess reached past the square)
    assert np.median(error) < 0.12 and np.percentile(error, 95) < 0.5, (
        np.median(error), np.percentile(error, 95),
    )  # fmt: skip
