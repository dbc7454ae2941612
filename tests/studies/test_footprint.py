"""The footprint truth a comparison converged on (``studies.footprint``)."""

import numpy as np
import pytest

from processing.btf import psnr_db, rmse
from sim import Simulator
from studies.footprint import converged_truth, truth_at
from tests.sim.sim_scenes import small_scene

PAIRS = (((22.0, 75.0), (38.0, 200.0)), ((40.0, 20.0), (38.0, 320.0)))
N = 16


@pytest.fixture(scope="module")
def weave():
    with Simulator(small_scene("weave", effects=["shadows"])) as sim:
        yield sim


def _score(measured, truth):
    return psnr_db(rmse(measured, truth), peak=float(truth.max()))


@pytest.mark.parametrize(
    ("generator", "effects", "size", "pairs"),
    [
        pytest.param("bumps", [], 8, PAIRS[:1], id="bumps"),  # 16 rays a side: under a second
        pytest.param("weave", ["shadows"], N, PAIRS, id="weave", marks=pytest.mark.slow),
    ],  # the weave: up to 128² rays a texel
)
def test_doubling_the_converged_rays_changes_the_score_by_less_than_the_tolerance(
    generator, effects, size, pairs
):
    with Simulator(small_scene(generator, effects=effects)) as sim:
        measured = truth_at(sim, pairs, size, 1)  # the centre ray: an aliased "measurement"
        result = converged_truth(sim, pairs, measured, start=2, most=64, tol_db=0.1)
        assert result.converged and result.change_db < 0.1
        doubled = truth_at(sim, pairs, size, 2 * result.rays)
    assert abs(_score(measured, doubled) - _score(measured, result.values)) < 0.1
    # and the footprint is not the centre ray's truth
    assert _score(measured, result.values) < 40.0


def test_a_comparison_that_does_not_converge_is_flagged_and_finite(weave):
    # scored against the 2-ray truth itself, the score drops from the 200 dB cap at 4 rays
    measured = truth_at(weave, PAIRS, N, 2)
    result = converged_truth(weave, PAIRS, measured, start=2, most=4)
    assert not result.converged and result.rays == 4
    assert np.isfinite(result.change_db) and result.change_db > 0.1


@pytest.mark.parametrize(("start", "most", "tol"), [(0, 4, 0.1), (4, 6, 0.1), (2, 8, 0.0)])
def test_bad_options_name_what_is_valid(weave, start, most, tol):
    with pytest.raises(ValueError, match="need 1 ≤ start, 2 · start ≤ most and tol_db > 0"):
        converged_truth(weave, PAIRS, np.zeros((2, N, N, 3)), start=start, most=most, tol_db=tol)
