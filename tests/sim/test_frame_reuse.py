"""Frames reused between steps equal the frames rendered from scratch.

The references were rendered by the simulator before hits, lamp visibility and
shading were reused between frames (``frame_sequence.py``):
``data/reference_clean_frames.npz`` without the ``noise`` effect (at 03de73c,
the noise-free part of image formation is unchanged since), and
``data/reference_frames.npz`` with it, its shot noise drawn from the exact
Poisson law. Tolerances: the noise-free signal before quantisation within
1e-9 DN (the reuse reorders float64 arithmetic only), its stored image equal;
the noise, now one Gaussian draw per pixel (``sim.sensor.add_noise``), agrees
with the reference's in distribution.
"""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from scipy import stats

from sim import Simulator
from sim.model import SceneModel
from sim.sensor import full_scale
from tests.sim.frame_sequence import (
    CLEAN_REFERENCE,
    REFERENCE,
    SEQUENCE,
    render_sequence,
    sequence_scene,
)


@pytest.fixture(scope="module")
def frames():
    with Simulator(sequence_scene(noise=False)) as sim:
        return render_sequence(sim), dict(sim.counters)


@pytest.fixture(scope="module")
def noisy_frames():
    with Simulator(sequence_scene()) as sim:
        return render_sequence(sim)


def test_frames_equal_the_reference(frames):
    rendered, _ = frames
    with np.load(CLEAN_REFERENCE) as ref:
        assert len(ref.files) == 2 * len(SEQUENCE)
        for k in range(len(SEQUENCE)):
            np.testing.assert_allclose(
                rendered[f"signal_{k}"], ref[f"signal_{k}"], rtol=0, atol=1e-9, err_msg=f"frame {k}"
            )
            np.testing.assert_array_equal(rendered[f"image_{k}"], ref[f"image_{k}"], f"frame {k}")


def test_the_noise_is_the_references_in_distribution(noisy_frames):
    """Noise standardised by the model's σ at each pixel's true signal: mean 0, variance 1
    and the same distribution as the exact Poisson draw's (Kolmogorov–Smirnov distance within
    the Gaussian draw's 0.7 % and the samples' own scatter), in every frame of the sequence."""
    scene = sequence_scene()
    noise = scene.spec.params("noise")
    gain = full_scale(8) / noise.full_well_e
    z = {"new": [], "reference": []}
    with np.load(CLEAN_REFERENCE) as clean, np.load(REFERENCE) as ref:
        for k in range(len(SEQUENCE)):
            truth = clean[f"signal_{k}"].astype(np.float64)
            sigma = np.sqrt(truth * gain + (noise.read_noise_e * gain) ** 2)
            # Away from the clipping at 0 and at full scale (the saturation effect).
            keep = (truth > 6 * sigma) & (truth < full_scale(8) - 6 * sigma)
            for name, frames_ in (("new", noisy_frames), ("reference", ref)):
                residual = frames_[f"signal_{k}"].astype(np.float64) - truth
                z[name].append((residual / sigma)[keep])
    new, reference = np.concatenate(z["new"]), np.concatenate(z["reference"])
    assert len(new) > 50_000 and not np.array_equal(new, reference)  # redrawn
    assert abs(new.mean()) < 0.02 and abs(reference.mean()) < 0.02
    assert new.var() == pytest.approx(1.0, abs=0.03)
    assert new.var() == pytest.approx(reference.var(), abs=0.03)
    assert stats.ks_2samp(new, reference).statistic < 0.015


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
