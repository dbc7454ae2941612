"""Frames reused between steps equal the frames rendered from scratch.

The reference (``data/reference_frames.npz``) was rendered by the simulator
before hits, lamp visibility and shading were reused between frames
(``frame_sequence.py``). Tolerance: the signal before quantisation within
1e-9 DN (the reuse reorders float64 arithmetic only), the stored image equal.
"""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from sim import Simulator
from sim.model import SceneModel
from tests.sim.frame_sequence import REFERENCE, SEQUENCE, render_sequence, sequence_scene


@pytest.fixture(scope="module")
def frames():
    with Simulator(sequence_scene()) as sim:
        return render_sequence(sim), dict(sim.counters)


def test_frames_equal_the_reference(frames):
    rendered, _ = frames
    with np.load(REFERENCE) as ref:
        assert len(ref.files) == 2 * len(SEQUENCE)
        for k in range(len(SEQUENCE)):
            np.testing.assert_allclose(
                rendered[f"signal_{k}"], ref[f"signal_{k}"], rtol=0, atol=1e-9, err_msg=f"frame {k}"
            )
            np.testing.assert_array_equal(rendered[f"image_{k}"], ref[f"image_{k}"], f"frame {k}")


def test_rays_that_cannot_meet_the_mesh_are_not_cast_and_answer_the_same():
    model = SceneModel(sequence_scene())
    mesh = model.mesh
    rng = np.random.default_rng(5)
    # Origins on the plate's top, just above it, and down in the recess among the yarns.
    xy = rng.uniform(-0.6, 0.6, (3000, 2)) * model.sample_mm
    z = rng.choice([1e-3, 0.5, -0.5, -2.0], 3000)
    origins = np.column_stack([xy, z])
    lamp = np.array([120.0, -40.0, 150.0])
    below = np.array([60.0, 10.0, -80.0])  # a point under the plate: every ray descends
    brute = trimesh.Trimesh(mesh.vertices, mesh.faces, process=False).ray
    for point in (lamp, below):
        dirs = point - origins
        dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
        expected = ~brute.intersects_any(origins, dirs)
        before = model.caster.rays
        np.testing.assert_array_equal(model.caster.sees(origins, point), expected)
        cast = model.caster.rays - before
        rising_above = (origins[:, 2] > 0) & (dirs[:, 2] >= 0)
        assert cast == len(origins) - rising_above.sum()
        assert expected.any() and not expected.all()  # both answers are exercised
