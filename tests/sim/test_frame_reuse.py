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

from dataclasses import replace

import numpy as np
import pytest
import trimesh
from scipy import stats

from sim import Simulator
from sim.illumination import visible_from
from sim.model import SceneModel
from sim.sensor import full_scale
from sim.shading import LightSource, SurfaceHits, triangle_hits
from tests.sim.frame_sequence import (
    CLEAN_REFERENCE,
    REFERENCE,
    SEQUENCE,
    render_sequence,
    sequence_scene,
)

LAMPS = [f"lamp{k}" for k in range(8)]


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


@pytest.mark.parametrize("kind", ["point", "spot", "directional"])
def test_the_compiled_surface_irradiance_is_the_incident_irradiance_times_the_cosine(kind):
    rng = np.random.default_rng(2)
    points = rng.uniform(-30, 30, (5000, 3))
    normals = rng.normal(size=(5000, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    light = LightSource(np.array([150.0, -60.0, 220.0]), kind, 7.0, cutoff_deg=4.0)
    dirs, e = light.surface_irradiance(points, normals)
    want_dirs, want_e = light.incident(points)
    cos_i = np.einsum("ij,ij->i", normals, want_dirs)
    np.testing.assert_allclose(dirs, want_dirs, rtol=0, atol=1e-15)
    # The cosine summed in another order: 1e-13 of the value where it nearly cancels.
    np.testing.assert_allclose(e, want_e * np.clip(cos_i, 0, None), rtol=1e-12, atol=1e-12)
    assert (e == 0).any() and (e > 0).any()  # both sides of the cosine (and of the spot's cone)


def test_shadow_rays_are_cast_only_where_the_lamp_lights_and_answer_as_for_all():
    """The lamp's visibility where its light falls (cosθ_i > 0, inside a spot's cone) is the
    visibility asked of every hit; fewer rays are cast."""
    with Simulator(sequence_scene(noise=False)) as sim:
        frame = sim.render_state("cam0", turntable_deg=37.5, arc_deg=60.0, lamps_on=["lamp5"])
        (hits,) = sim._hits.values()
        model = sim.model
        light = model.lights(frame.snapshot)["lamp5"]
        _, e = light.surface_irradiance(hits.points, hits.normals)
        lit = e > 0
        before = model.caster.rays
        every = visible_from(model, hits, light.position, offset_mm=1e-3)
        all_rays = model.caster.rays - before
        some = visible_from(model, hits, light.position, offset_mm=1e-3, where=lit)
        lit_rays = model.caster.rays - before - all_rays
    np.testing.assert_array_equal(some[lit], every[lit])
    assert not some[~lit].any() and (~lit).sum() > 100 and lit_rays < all_rays
    assert not every[lit].all()  # some lit hits are in shadow


def test_the_compiled_hit_reconstruction_is_numpys():
    """Rays from a camera on random faces of the default mesh (some behind their origin,
    some parallel to their face): the kept rays, points, normals facing the viewer and
    view directions are those numpy's arithmetic gives, to the last bits' reordering."""
    mesh = SceneModel(sequence_scene()).mesh
    rng = np.random.default_rng(8)
    faces = rng.integers(0, len(mesh.faces), 4000)
    tri = mesh.vertices[mesh.faces[faces]]
    w = rng.dirichlet([1, 1, 1], 4000)
    origin = np.array([40.0, -25.0, 60.0])
    dirs = np.einsum("ij,ijk->ik", w, tri) - origin
    dirs[:100] *= -1  # the face behind the origin
    dirs[100:200] = np.cross(tri[100:200, 1] - tri[100:200, 0], tri[100:200, 2] - tri[100:200, 0])
    dirs[100:200] = np.cross(dirs[100:200], tri[100:200, 1] - tri[100:200, 0])  # in the plane
    hits = SurfaceHits.build(mesh, (50, 80), np.arange(4000), origin, dirs, faces,
                             lambda points, materials: np.ones((len(points), 3)))  # fmt: skip
    t, u, v = triangle_hits(origin, dirs, tri)
    keep = np.isfinite(t) & (t > 0)
    assert not keep[:200].any() and keep[200:].all()
    np.testing.assert_array_equal(hits.pixels, np.flatnonzero(keep))
    t, u, v, d, f = t[keep], u[keep], v[keep], dirs[keep], faces[keep]
    vn = mesh.normals[mesh.faces[f]]
    normals = (1 - u - v)[:, None] * vn[:, 0] + u[:, None] * vn[:, 1] + v[:, None] * vn[:, 2]
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    view = -d / np.linalg.norm(d, axis=1, keepdims=True)
    back = np.einsum("ij,ij->i", normals, view) < 0
    normals[back] *= -1
    assert 0 < back.sum() < len(back)
    np.testing.assert_allclose(hits.points, origin + t[:, None] * d, rtol=0, atol=1e-11)
    np.testing.assert_allclose(hits.normals, normals, rtol=0, atol=1e-11)
    np.testing.assert_allclose(hits.view_dirs, view, rtol=0, atol=1e-15)


def test_shadow_rays_from_a_views_hits_answer_as_trimeshs_embree_intersector():
    """The compiled shadow rays and Embree's occlusion query give, ray for ray, what
    trimesh's intersector answers for the same rays (grazing rays off the yarns included)."""
    with Simulator(sequence_scene(noise=False, scale=0.25)) as sim:
        frame = sim.render_state("cam3", turntable_deg=37.5, arc_deg=20.0, lamps_on=["lamp2"])
        (hits,) = sim._hits.values()
        model = sim.model
        lights = model.lights(replace(frame.snapshot, lamps_on=frozenset(LAMPS)))
    brute = trimesh.Trimesh(model.mesh.vertices, model.mesh.faces, process=False).ray
    origins = hits.points + 1e-3 * hits.normals
    blocked = 0
    for light in lights.values():
        dirs = light.position - origins
        dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
        expected = ~brute.intersects_any(origins, dirs)
        np.testing.assert_array_equal(model.caster.sees(origins, light.position), expected)
        blocked += (~expected).sum()
    assert blocked > 1000
