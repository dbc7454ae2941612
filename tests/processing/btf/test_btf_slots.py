"""Grouping archived BTF steps into view slots × lights."""

from __future__ import annotations

import numpy as np
import pytest

from processing.btf import BtfError, view_slots
from rig.archive import StepRecord

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
