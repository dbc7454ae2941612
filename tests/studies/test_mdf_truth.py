"""The exact MDF by ray casting a relief, on a floor with a known answer."""

import numpy as np
import trimesh

from processing.mdf import Reason
from rig.geometry import texel_centers_mm
from studies.mdf_truth import ray_cast_mdf


def test_a_floor_1_mm_down_gives_1_over_cos_theta_and_unseen_past_its_edge():
    floor = trimesh.Trimesh([[-5, -5, -1], [5, -5, -1], [5, 5, -1], [-5, 5, -1]],
                            [[0, 1, 2], [0, 2, 3]])  # fmt: skip
    mdf = ray_cast_mdf(floor, [[0.0, 0.0], [60.0, 0.0]], sample_mm=10.0, n=20, source="floor")
    np.testing.assert_allclose(mdf.distance_mm[0], 1.0, atol=1e-6)
    # Seen from θ = 60° towards +x the ray runs tan 60° = 1.73 mm towards −x before it lands:
    # texels closer than that to the −x edge see past the floor.
    x = texel_centers_mm(10.0, 20)[..., 0]
    past = x - np.tan(np.radians(60.0)) < -5.0
    np.testing.assert_allclose(mdf.distance_mm[1][~past], 2.0, atol=1e-6)
    assert np.all(mdf.distance_mm[1][past] == -1) and past.sum() == 3 * 20
    assert np.all(mdf.reason[1][past] == Reason.UNLIT) and np.all(mdf.count[1][past] == 0)
    assert mdf.attrs == {"source": "floor"}
