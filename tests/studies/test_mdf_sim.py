"""``rig bench mdf-sim --quick``: the bumps scanned end to end from 1 and 5 laser locations,
against the simulator's ray-cast MDF (docs/mdf.md has the full table)."""

import pytest

from studies.mdf_sim import run

# Sessions, subprocesses or benches: the full tier only (make test), not make quick.
pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def rows():
    return {row["locations"]: row for row in run(quick=True)}


def test_more_locations_see_more_and_measure_closer(rows):
    one, five = rows["1"], rows["5"]
    # Measured: coverage 0.910 → 1.000, median error 0.049 → 0.026 mm (128² texels of 0.78 mm).
    assert five["coverage"] > one["coverage"] and five["coverage"] >= 0.99
    assert five["median_mm"] < one["median_mm"] and five["median_mm"] < 0.05
    assert five["rig_s"] > one["rig_s"]  # what the accuracy costs in capture time
