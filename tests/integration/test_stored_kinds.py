"""A session of each rig kind recorded today equals the one stored before rig kinds became
modules (tests/data/stored_kinds): the same steps, directions and actuators (numbers to
1e-9: their last bits follow the arithmetic of the pose conversions) and frames, bit for
bit."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from orchestrator.local import run_local
from rig.archive import Archive
from rig.clock import VirtualClock
from sim.rig import SimulatedRig
from sim.scene import scene_from_dict

# Sessions, subprocesses or benches: the full tier only (make test), not make quick.
pytestmark = pytest.mark.slow

STORED = Path(__file__).resolve().parents[1] / "data" / "stored_kinds"
WANG = {"camera_arc": {"cameras": [{"id": "cam0", "theta_deg": 0.0},
                                   {"id": "cam1", "theta_deg": 30.0}]},
        "light_arc": {"lamps": [{"id": "lamp0", "theta_deg": 45.0}]}}  # fmt: skip
SESSIONS = {  # as the stored ones were recorded (tests/data/stored_kinds/README.md)
    "wang": ({"overrides": WANG}, "[captures.btf]\nviews = [[0, 0], [30, 90]]\nlights = [[45, 0]]"),
    "bonn": ({"kind": "bonn"}, "[captures.btf]\nviews = [[0, 0], [34, 150]]\nlights = [[34, 90]]"),
    "virtex": (
        {"kind": "virtex", "overrides": {"virtex": {"lamp_count": 3}}},
        "[captures.ps]\nviews = [[0, 0]]\nlights = { theta_deg = 45, count = 3 }",
    ),
}


def _recorded(path: Path):
    with Archive.open(path) as archive:
        steps = archive.step_table()
        frames = {
            (s.index, c, sub): archive.read_frame(s.index, c, sub)
            for s in steps for c in s.cameras for sub in range(len(s.exposures_s))
        }  # fmt: skip
        config = archive.rig_config
    # Not the steps' start times: a frame the camera re-sends on a loaded machine moves the
    # virtual clock, not what a step records or captures.
    rows = [
        (s.index, s.kind, s.cameras, s.views_deg, s.light_deg, s.actuators, s.exposures_s,
         s.lamp, s.laser)
        for s in steps
    ]  # fmt: skip
    return config, rows, frames


@pytest.mark.parametrize("kind", sorted(SESSIONS))
def test_a_session_recorded_today_equals_the_stored_one(kind, tmp_path):
    rig, captures = SESSIONS[kind]
    scene = scene_from_dict({
        "name": f"stored-{kind}", "effects": [],
        "sample": {"generator": "flat", "depth_mm": 0.01},
        "rig": rig, "render": {"scale": 0.03, "supersample": 1},
    })  # fmt: skip
    plan = tmp_path / "plan.toml"
    plan.write_text(f'[sample]\nname = "{kind}"\n{captures}\n[exposure]\nexposure_s = 0.05\n')
    clock = VirtualClock()
    with SimulatedRig(scene, clock=clock) as sim:
        final = run_local(plan, sim.rig_config(), archive=tmp_path / "s.zarr", clock=clock)
    assert final["state"] == "done", final
    config, rows, frames = _recorded(tmp_path / "s.zarr")
    stored_config, stored_rows, stored_frames = _recorded(STORED / f"{kind}.zarr")
    assert len(rows) == len(stored_rows)
    for row, stored in zip(rows, stored_rows, strict=True):
        assert _close(row, stored), (row, stored)
    assert frames.keys() == stored_frames.keys()
    for key, frame in frames.items():
        np.testing.assert_array_equal(frame, stored_frames[key], err_msg=str(key))
    assert _no_addresses(config) == _no_addresses(stored_config)


def _close(a, b) -> bool:
    """Equal trees, floats within 1e-9 (degrees, millimetres, seconds)."""
    if isinstance(a, float) or isinstance(b, float):
        return isinstance(a, int | float) and isinstance(b, int | float) and abs(a - b) <= 1e-9
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_close(a[k], b[k]) for k in a)
    if isinstance(a, tuple | list) and isinstance(b, tuple | list):
        return len(a) == len(b) and all(_close(x, y) for x, y in zip(a, b, strict=True))
    return a == b


def _no_addresses(tree):
    """The config without the peers' addresses (ports, serial ports, URLs), which differ run
    to run."""
    if isinstance(tree, dict):
        return {k: _no_addresses(v) for k, v in tree.items()
                if not k.endswith("port") and k not in ("url", "host")}  # fmt: skip
    if isinstance(tree, list):
        return [_no_addresses(v) for v in tree]
    return tree
