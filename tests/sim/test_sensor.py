"""Lens and sensor effects: noise statistics, distortion, saturation, laser line."""

import numpy as np
import pytest
from scipy import stats

from rig.camera import PinholeCamera
from rig.kinematics import laser_plane
from sim import Simulator, sensor
from sim.sensor import add_noise, distort, distortion_maps, quantize, standard_normal
from tests.sim.sim_scenes import small_scene


def test_noise_mean_and_variance_follow_the_model():
    rng = np.random.default_rng(3)
    signal = np.full(200_000, 100.0)
    noisy = add_noise(signal, bit_depth=8, full_well_e=10_000, read_noise_e=5.0, rng=rng)
    g = 255 / 10_000
    assert noisy.mean() == pytest.approx(100.0, abs=0.02)
    assert noisy.var() == pytest.approx(100 * g + (5 * g) ** 2, rel=0.02)
    q = quantize(noisy, np.uint8)
    assert q.var() == pytest.approx(100 * g + (5 * g) ** 2 + 1 / 12, rel=0.03)


def test_the_compiled_normal_draw_follows_the_normal_law_into_its_tails():
    """Counts in bins out to the ziggurat's tail (beyond 3.654) and its last layers against
    the normal law's (chi-square), from two million draws."""
    rng = np.random.default_rng(11)
    z = standard_normal(rng, (1000, 2000))
    assert z.shape == (1000, 2000) and z.dtype == np.float32
    edges = np.array([-np.inf, -4, -3.654, -3.449, -3, -2, -1, 0, 1, 2, 3, 3.449, 3.654, 4, np.inf])
    expected = np.diff(stats.norm.cdf(edges)) * z.size
    observed = np.histogram(z, edges)[0]
    assert stats.chisquare(observed, expected).pvalue > 1e-3
    assert observed[[0, -1]].sum() > 80  # the tail beyond 4 is drawn (127 expected)
    assert not np.array_equal(standard_normal(rng, (100,)), standard_normal(rng, (100,)))


def test_a_draw_that_runs_out_of_words_goes_on_where_it_stopped():
    words = np.random.default_rng(4).bit_generator.random_raw(600).view(np.uint32)
    whole = np.empty(1000, np.float32)
    assert (
        sensor._ziggurat(words, whole, 0, sensor._KI, sensor._WI, sensor._FI, sensor._ZIG_R) == 1000
    )
    part = np.empty(1000, np.float32)
    reached = sensor._ziggurat(words[:500], part, 0, sensor._KI, sensor._WI, sensor._FI,
                               sensor._ZIG_R)  # fmt: skip
    assert 450 < reached < 500  # one word a value, more where one is rejected
    np.testing.assert_array_equal(part[:reached], whole[:reached])
    more = np.random.default_rng(5).bit_generator.random_raw(600).view(np.uint32)
    assert sensor._ziggurat(more, part, reached, sensor._KI, sensor._WI, sensor._FI,
                            sensor._ZIG_R) == 1000  # fmt: skip
    assert np.isfinite(part).all() and not np.array_equal(part[reached:], whole[reached:])


def test_rendered_noise_is_normalised_around_the_truth():
    scene = small_scene("bumps", effects=["noise"], params={"grid": 33},
                        noise={"read_noise_e": 20.0, "full_well_e": 2000.0, "seed": 7})  # fmt: skip
    with Simulator(scene) as sim:
        a = sim.render_state("cam1", lamps_on=["lamp2"])
        b = sim.render_state("cam1", lamps_on=["lamp2"])
        assert not np.array_equal(a.image, b.image)  # fresh noise each frame
        truth = sim.image_truth("cam1", a.snapshot)
        g = 255 / 2000
        sel = truth > 5
        z = (a.signal[sel] - truth[sel]) / np.sqrt(truth[sel] * g + (20 * g) ** 2)
        assert abs(z.mean()) < 0.05
        assert z.std() == pytest.approx(1.0, abs=0.05)


def test_distortion_moves_points_where_project_says():
    K = np.array([[300.0, 0, 79.5], [0, 300.0, 59.5], [0, 0, 1]])
    dist = np.array([-0.5, 0.1, 0.002, -0.001, 0.0])
    R, t = np.eye(3), np.zeros(3)
    pinhole = PinholeCamera(K, np.zeros(5), R, t, 160, 120)
    lens = PinholeCamera(K, dist, R, t, 160, 120)
    u, v = np.meshgrid(np.arange(160), np.arange(120))
    for point in ([0.2, 0.15, 1.0], [-0.2, 0.12, 1.0], [0.1, -0.17, 1.0]):
        p0 = pinhole.project([point])[0][0]
        blob = np.exp(-((u - p0[0]) ** 2 + (v - p0[1]) ** 2) / (2 * 1.5**2))
        out = distort(blob, distortion_maps(lens))
        centroid = np.array([np.sum(out * u), np.sum(out * v)]) / out.sum()
        expected = lens.project([point])[0][0]
        assert np.linalg.norm(centroid - expected) < 0.1
        assert np.linalg.norm(expected - p0) > 1.0  # the distortion did move it


def test_saturation_clips_at_full_scale():
    scene = small_scene("flat", effects=["saturation"], radiometry={"full_scale_exposure": 0.01})
    with Simulator(scene) as sim:
        frame = sim.render_state("cam0", lamps_on=["lamp0"])
        assert frame.signal.max() == 255.0
        assert frame.image.dtype == np.uint8


def test_laser_line_lies_on_the_laser_plane():
    scene = small_scene("bumps", effects=["laser"], scale=0.25, params={"grid": 33},
                        laser={"width_mm": 1.0})  # fmt: skip
    with Simulator(scene) as sim:
        tilt, arc, tt = 3.0, 20.0, 35.0
        frame = sim.render_state("cam0", turntable_deg=tt, arc_deg=arc, laser=True,
                                 laser_tilt_deg=tilt)  # fmt: skip
        truth = sim.truth("cam0", tt)
        n, d = laser_plane(scene.rig, arc_deg=arc, mount=0, tilt_deg=tilt, turntable_deg=tt)
        img = frame.signal.mean(axis=2)
        bright = img > 0.5 * img.max()
        on_plate = bright & (truth.part == 0)
        assert on_plate.sum() > 20
        dist = truth.points[on_plate] @ n - d
        assert np.abs(dist).max() < 1.2  # half maximum of σ = 1 mm is at 1.18 mm
        assert np.all(np.abs(truth.points[on_plate][:, 2]) < 1e-4)  # on z = 0
        far = np.abs(truth.points[..., :] @ n - d) > 5
        assert img[far & truth.mask].max() < 1e-3 * img.max()  # Gaussian tail only
