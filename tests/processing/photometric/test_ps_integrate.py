"""Height from normals: accuracy of each integrator, conventions, edge cases."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from processing.photometric import (
    NearLights,
    PhotometricError,
    PixelGrid,
    gradients_from_normals,
    integrate_gradients,
    integrate_normals,
    refine_near,
)
from tests.processing.photometric.ps_synthetic import (
    angular_error_deg,
    bumps,
    render_near,
    ring_directions,
)


@pytest.fixture(scope="module")
def surface():
    return bumps(96, seed=2)


def rmse_up_to_offset(height, truth, mask=None):
    d = (height - truth) if mask is None else (height - truth)[mask]
    return float(np.sqrt(np.mean((d - d.mean()) ** 2)))


# Tolerances, against a height range of ~0.8 mm on a 96² grid at 0.1 mm pitch:
# DCT and masked LSQ use finite differences of the exact slopes (O(pitch²)
# truncation, ~2e-4 mm); Frankot–Chellappa is spectral and the bumps vanish
# at the border, so it is near exact.
@pytest.mark.parametrize(("method", "tolerance_mm"), [("dct", 5e-4), ("fc", 1e-5), ("lsq", 5e-4)])
def test_height_rmse_per_integrator(surface, method, tolerance_mm):
    height = integrate_normals(surface.normals, pitch_mm=surface.pitch_mm, method=method)
    assert height.method == method and height.height_mm.dtype == np.float32
    assert rmse_up_to_offset(height.height_mm, surface.height) < tolerance_mm
    assert height.height_mm.max() == 0  # the highest point is the reference plane
    assert np.ptp(surface.height) > 0.5  # the test is not trivially flat


def test_masked_lsq_on_an_irregular_mask(surface):
    mask = np.ones(surface.height.shape, bool)
    mask[:30, :20] = False
    mask[60:70, 40:] = False
    mask[80:, 10:12] = False
    height = integrate_normals(surface.normals, pitch_mm=surface.pitch_mm, mask=mask)
    assert height.method == "lsq"
    assert rmse_up_to_offset(height.height_mm, surface.height, mask) < 5e-4
    assert np.all(height.height_mm[~mask] == 0) and np.array_equal(height.valid, mask)


def test_lsq_equals_dct_on_the_full_rectangle(surface):
    grads = gradients_from_normals(surface.normals)
    dct = integrate_gradients(grads.p, grads.q, pitch_mm=0.1, method="dct").height_mm
    lsq = integrate_gradients(grads.p, grads.q, pitch_mm=0.1, method="lsq").height_mm
    assert_allclose(dct, lsq, atol=1e-6)  # the same least-squares problem, two solvers


def test_sign_convention_on_a_tilted_plane():
    # z rises along +x (p = 0.2) and along +y (q = 0.1); rows run along -y.
    n = np.array([-0.2, -0.1, 1.0]) / np.linalg.norm([-0.2, -0.1, 1.0])
    normals = np.broadcast_to(n, (5, 7, 3))
    grads = gradients_from_normals(normals)
    assert_allclose(grads.p, 0.2) and assert_allclose(grads.q, 0.1)
    for method in ("dct", "fc", "lsq"):
        h = integrate_normals(normals, pitch_mm=2.0, method=method).height_mm
        if method != "fc":  # a plane is not periodic; FC only gets its mean slope wrong
            assert_allclose(np.diff(h, axis=1), 0.4, atol=1e-5)
            assert_allclose(np.diff(h, axis=0), -0.2, atol=1e-5)


@given(nz=st.floats(-1.0, 0.2), azimuth=st.floats(0, 6.3), limit=st.floats(30, 89))
def test_steep_and_downward_normals_are_clipped_and_flagged(nz, azimuth, limit):
    lateral = np.sqrt(max(0.0, 1 - nz * nz))
    n = np.array([lateral * np.cos(azimuth), lateral * np.sin(azimuth), nz])
    normals = np.tile(n, (3, 4, 1))
    normals[0, 0] = [0, 0, 1]
    grads = gradients_from_normals(normals, max_slope_deg=limit)
    slope = np.hypot(grads.p, grads.q)
    assert np.all(np.isfinite(slope)) and np.all(slope <= np.tan(np.deg2rad(limit)) * (1 + 1e-9))
    steep = nz <= 0 or lateral > np.tan(np.deg2rad(limit)) * nz
    assert grads.clipped[1, 1] == steep and not grads.clipped[0, 0]
    height = integrate_gradients(grads.p, grads.q, pitch_mm=1.0)
    assert np.all(np.isfinite(height.height_mm))


def test_refine_near_converges_to_the_surface(surface):
    placed_height = surface.height - surface.height.max()
    from tests.processing.photometric.ps_synthetic import Surface

    placed = Surface(surface.x, surface.y, placed_height, surface.normals, surface.albedo, 0.1)
    positions = ring_directions(24) * 60.0
    images = render_near(placed, positions)
    grid = PixelGrid((96, 96), 0.1)
    errors = []
    for iterations in (0, 2):
        out = refine_near(
            images, NearLights(positions), grid=grid, iterations=iterations, method="lsq"
        )
        errors.append(angular_error_deg(out.result.normals, surface.normals).mean())
    assert errors[1] < 0.1 * errors[0] and errors[1] < 0.001
    assert rmse_up_to_offset(out.height.height_mm, surface.height) < 5e-4


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"pitch_mm": 0.0}, "pitch_mm"),
        ({"pitch_mm": 1.0, "method": "poisson"}, "method: 'poisson'"),
        ({"pitch_mm": 1.0, "mask": np.ones((2, 2), bool)}, "mask: expected a bool array"),
    ],
)
def test_bad_integration_arguments(kwargs, match):
    with pytest.raises(PhotometricError, match=match):
        integrate_gradients(np.zeros((3, 3)), np.zeros((3, 3)), **kwargs)
