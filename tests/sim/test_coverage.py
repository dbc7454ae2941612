"""The reachable set of MDF scans on the weave, on a small texel grid.

The weave's recess floor shows through the gaps between yarns; a sheet from
45° never reaches it past the yarns, a steeper mount does.
"""

import tomllib
from pathlib import Path

import numpy as np
import pytest

from sim.coverage import (
    LaserReach,
    candidate_locations,
    capture_s,
    choose_locations,
    coverage_rows,
    laser_reach,
)
from sim.model import SceneModel
from sim.scene import scene_from_dict
from sim.truth import mdf_truth

N = 48
SCENES = Path(__file__).parents[2] / "examples" / "scenes"


def _model(name: str, **sample) -> SceneModel:
    data = tomllib.loads((SCENES / f"{name}.toml").read_text())
    data["sample"].update(sample)
    return SceneModel(scene_from_dict(data))


@pytest.fixture(scope="module")
def weave():
    return _model("default")


def _with_mounts(config, *angles, **laser):
    update = {"mount_theta_deg": angles, **laser}
    return config.model_copy(update={"laser": config.laser.model_copy(update=update)})


def test_visible_texels_are_those_with_a_true_mdf(weave):
    reach = laser_reach(weave, weave.scene.rig, (30.0, 90.0), [[45.0, 0.0]], N)
    np.testing.assert_array_equal(reach.visible, mdf_truth(weave, (30.0, 90.0), N) >= 0)
    assert not np.any(reach.reached & ~reach.visible)


def test_a_45_degree_mount_misses_the_recess_floor_a_steeper_one_reaches_it(weave):
    rig = _with_mounts(weave.scene.rig, 45.0, 20.0)
    candidates = candidate_locations(rig, azimuths=12)
    assert candidates.shape == (24, 2)
    reach = laser_reach(weave, rig, (0.0, 0.0), candidates, N)
    at_45 = np.flatnonzero(candidates[:, 0] == 45.0)
    assert 0.85 < reach.coverage(at_45) < 0.95  # all 12 azimuths at 45°
    chosen = choose_locations(reach, goal=0.99)
    assert reach.coverage(chosen) >= 0.99
    assert len(chosen) <= 3 and set(candidates[chosen, 0]) == {20.0}
    # Keeping the 45° locations first, the steep ones complete them.
    kept = choose_locations(reach, goal=0.99, start=at_45[::3])
    assert kept[:4] == list(at_45[::3]) and reach.coverage(kept) >= 0.99


def test_a_flat_target_is_covered_by_one_location():
    flat = _model("flat_target")
    reach = laser_reach(flat, flat.scene.rig, (0.0, 0.0), [[45.0, 0.0]], N)
    # The emitter stands at +x; the recess wall there shadows the 2 mm next to it, in the
    # margin around the measured square.
    assert not (reach.visible & ~reach.reached[0]).any()
    # With the wall on the square's edge its shadow takes the last column.
    walled = _model("flat_target", margin_mm=0.0)
    reach = laser_reach(walled, walled.scene.rig, (0.0, 0.0), [[45.0, 0.0]], N)
    unreached = reach.visible & ~reach.reached[0]
    assert unreached[:, -1].all() and not unreached[:, :-1].any()
    flat = _model("flat_target")
    # A 1° sweep moves the strip only ±6 mm over the 100 mm sample.
    narrow = _with_mounts(flat.scene.rig, 45.0, sweep_deg=1.0)
    band = laser_reach(flat, narrow, (0.0, 0.0), [[45.0, 0.0]], N)
    assert 0.05 < band.coverage() < 0.2


def test_sheets_grazing_the_view_ray_do_not_count(weave):
    rig = weave.scene.rig
    # From θ = 5° the untilted sheet is within 5° of the frontal view ray (gain
    # 11.5 > 10); only the sheets tilted away from it count.
    coverage = [
        laser_reach(weave, rig, (0.0, 0.0), [[5.0, 0.0]], N, max_error_gain=gain).coverage()
        for gain in (10.0, 20.0, 1000.0)
    ]
    assert coverage[0] < 0.5 < coverage[1] < 0.9 < coverage[2]


def test_the_greedy_choice_stops_when_nothing_is_gained():
    visible = np.ones((2, 2), bool)
    reached = np.array([[[1, 0], [0, 0]], [[1, 1], [0, 0]], [[1, 1], [0, 0]]], bool)
    reach = LaserReach(visible, reached, np.zeros((3, 2)))
    assert choose_locations(reach, goal=1.0) == [1]
    assert reach.coverage([1]) == 0.5
    with pytest.raises(ValueError, match="goal"):
        choose_locations(reach, goal=0.0)


def test_rows_set_coverage_beside_capture_time(weave):
    rows = coverage_rows(
        weave, weave.scene.rig, (0.0, 0.0), mounts=[(45.0,), (45.0, 20.0)], even=(1, 4),
        start=4, n=32, azimuths=12,
    )  # fmt: skip
    choices = [(row["mounts"], row["choice"]) for row in rows]
    assert choices == [
        ((45.0,), "1 even at 45°"), ((45.0,), "4 even at 45°"),
        ((45.0, 20.0), "greedy to 99%"), ((45.0, 20.0), "4 even + greedy"),
    ]  # fmt: skip
    assert rows[0]["coverage"] < rows[1]["coverage"] < 0.95 <= 0.99 <= rows[3]["coverage"]
    rig = _with_mounts(weave.scene.rig, 45.0, 20.0)
    assert rows[3]["capture_s"] == pytest.approx(capture_s(rig, (0.0, 0.0), rows[3]["locations"]))
    assert rows[0]["capture_s"] < rows[1]["capture_s"] < rows[3]["capture_s"]
