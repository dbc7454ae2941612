"""Grouping archived BTF steps into view slots × lights."""

from __future__ import annotations

import numpy as np
import pytest

from processing.btf import BtfError, view_slots
from rig import bonn
from rig.archive import StepRecord
from rig.config import RigConfig
from rig.geometry import Sampling, angular_distance_deg, direction_vector
from tests.rig.bonn_records import recorded_actuators

LIGHTS = [(0.0, 0.0), (30.0, 90.0), (60.0, 180.0)]


def _steps(drop=None, duplicate=False):
    steps, index = [], 0
    for light in LIGHTS:
        for turn in (0.0, 120.0):
            views = {"cam0": (0.0, 0.0), "cam2": (30.0, turn)} if turn == 0.0 else {
                "cam2": (30.0, turn)}  # fmt: skip
            if drop == (turn, light):
                continue
            steps.append(StepRecord(index, "btf", tuple(views), views, light))
            index += 1
    steps.append(StepRecord(index, "mdf", ("cam1",), {"cam1": (15.0, 0.0)}, None))
    if duplicate:
        steps.append(StepRecord(index + 1, "btf", ("cam2",), {"cam2": (30.0, 0.2)}, LIGHTS[0]))
    return steps


def test_steps_group_into_slots_and_lights():
    table = view_slots(_steps())
    np.testing.assert_allclose(table.view_dirs_deg, [[0, 0], [30, 0], [30, 120]])
    np.testing.assert_allclose(table.light_dirs_deg, LIGHTS)
    assert table.steps.shape == (3, 3)
    # Light 1, turntable 0 was step 2: cam0 serves the frontal slot, cam2 the 30° one.
    assert table.steps[0, 1] == 2 and table.cameras[0, 1] == "cam0"
    assert table.steps[1, 1] == 2 and table.cameras[1, 1] == "cam2"
    assert table.steps[2, 2] == 5


def test_missing_and_duplicated_captures_are_named():
    with pytest.raises(BtfError, match=r"not captured.*\(30.0, 120.0\)"):
        view_slots(_steps(drop=(120.0, LIGHTS[1])))
    with pytest.raises(BtfError, match="captured twice"):
        view_slots(_steps(duplicate=True))
    with pytest.raises(BtfError, match="kind 'ps'"):
        view_slots(_steps(), kind="ps")


def test_gaps_are_marked_when_accepted():
    table = view_slots(_steps(drop=(120.0, LIGHTS[1])), gaps=True)
    assert table.steps[2, 1] == -1 and table.cameras[2, 1] == ""
    assert (np.delete(table.steps.ravel(), 2 * 3 + 1) >= 0).all()


def test_a_displaced_capture_fills_the_cell_it_was_asked_for_and_is_listed():
    # the Bonn lab's retro pair (0°, 0°) × (0°, 0°): the rail's end leaves view and light
    # 5° to either side of it; the other cells were hit
    grid_views, grid_lights = [(0.0, 0.0), (30.0, 90.0)], [(0.0, 0.0), (45.0, 180.0)]
    steps, index = [], 0
    for view in grid_views:
        for light in grid_lights:
            recorded = ((5.0, 90.0), (5.0, 270.0)) if view == light else (view, light)
            steps.append(StepRecord(index, "btf", ("cam0",), {"cam0": recorded[0]}, recorded[1]))
            index += 1
    with pytest.raises(BtfError, match="not captured"):
        view_slots(steps)
    table = view_slots(steps, displaced_by_deg={0: 5.0, 1: 0.0})
    np.testing.assert_allclose(table.view_dirs_deg, grid_views)
    # lights in order of first capture on the grid: step 1's, then step 2's
    np.testing.assert_allclose(table.light_dirs_deg, grid_lights[::-1])
    assert table.steps.tolist() == [[1, 0], [3, 2]]
    (moved,) = table.displaced
    assert (moved.slot, moved.light, moved.step, moved.camera) == (0, 1, 0, "cam0")
    assert moved.view_deg == (5.0, 90.0) and moved.light_deg == (5.0, 270.0)
    # a displacement bound smaller than the step's offset finds no cell: it is its own slot
    with pytest.raises(BtfError, match="not captured"):
        view_slots(steps, displaced_by_deg={0: 2.0})


def test_h1_on_the_bonn_lab_fills_its_grid_with_the_retro_pairs_displaced():
    config = RigConfig.model_validate({"kind": "bonn", "bonn": {}})
    h1 = Sampling.named("H1").directions
    steps, bounds = [], {}
    for view in h1[:7]:  # the frontal view and the first ring: every light of H1 each
        for light in h1:
            pose = bonn.inverse(config, tuple(view), tuple(light))
            actuators = recorded_actuators(pose.rotation, pose.rail_deg)
            got_view, got_light = bonn.forward(config, pose.rotation, pose.rail_deg)
            index = len(steps)
            steps.append(StepRecord(index, "btf", ("cam0",), {"cam0": tuple(got_view)},
                                    tuple(got_light), actuators))  # fmt: skip
            bounds[index] = bonn.displaced_by_deg(config, actuators)
    table = view_slots(steps, displaced_by_deg=bounds)
    assert (table.steps >= 0).all()
    # the grid is the plan's (in order of first capture), each retro cell the displaced one
    views, lights = _match(table.view_dirs_deg, h1[:7]), _match(table.light_dirs_deg, h1)
    assert sorted(views) == list(range(7)) and sorted(lights) == list(range(len(h1)))
    assert sorted((views[d.slot], lights[d.light]) for d in table.displaced) == [
        (j, j) for j in range(7)
    ]


def _match(got_deg, want_deg) -> list[int]:
    """For each of ``got_deg``, the index of the direction of ``want_deg`` it is (< 1e-6°)."""
    got = direction_vector(*np.asarray(got_deg).T)
    want = direction_vector(*np.asarray(want_deg).T)
    gaps = angular_distance_deg(got[:, None, :], want[None, :, :])
    assert (gaps.min(axis=1) < 1e-6).all(), gaps.min(axis=1).max()
    return gaps.argmin(axis=1).tolist()
