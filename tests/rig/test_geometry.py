import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from rig.errors import ConfigError
from rig.geometry import (
    LIGHT_COSINE_FLOOR,
    Sampling,
    angular_distance_deg,
    barycentric_weights,
    carry_light_cosine,
    direction_angles,
    direction_vector,
    nearest_directions,
    spherical_triangulation,
    texel_centers_mm,
)

thetas = st.floats(0, 90, allow_nan=False)
phis = st.floats(0, 359.999, allow_nan=False)


@given(thetas, phis)
def test_angles_round_trip(theta, phi):
    v = direction_vector(theta, phi)
    assert_allclose(np.linalg.norm(v), 1.0, atol=1e-12)
    t, p = direction_angles(v)
    assert_allclose(t, theta, atol=1e-6)
    if theta > 1e-6:
        assert_allclose(angular_distance_deg(direction_vector(t, p), v), 0.0, atol=1e-6)


def test_convention_axes():
    assert_allclose(direction_vector(0, 123), [0, 0, 1], atol=1e-15)
    assert_allclose(direction_vector(90, 0), [1, 0, 0], atol=1e-15)
    assert_allclose(direction_vector(90, 90), [0, 1, 0], atol=1e-15)
    assert direction_angles([0, 0, 1])[1] == 0.0


def test_zero_vector_rejected():
    with pytest.raises(ValueError, match="zero vector"):
        direction_angles([0, 0, 0])


@pytest.mark.parametrize(
    ("name", "thetas"), [("H1", [0, 17, 34, 51, 68, 85]), ("H2", [0, 15, 30, 45, 60, 75])]
)
def test_seed_samplings_table1(name, thetas):
    s = Sampling.named(name)
    assert len(s) == 81
    rings = s.rings()
    assert list(rings) == thetas
    assert [len(i) for i in rings.values()] == [1, 6, 12, 18, 20, 24]
    # Azimuths equally spaced within each ring, starting at 0.
    for idx in rings.values():
        phi = np.sort(s.directions[idx, 1])
        assert phi[0] == 0.0
        if len(phi) > 1:
            assert_allclose(np.diff(phi), 360.0 / len(phi))


def test_custom_sampling_validation():
    with pytest.raises(ConfigError, match="theta 95"):
        Sampling("mine", np.array([[95.0, 0.0]]))
    with pytest.raises(ConfigError, match="same"):
        Sampling("mine", np.array([[10.0, 0.0], [10.0, 360.0]]))
    with pytest.raises(ConfigError, match="valid names"):
        Sampling.named("H3")
    s = Sampling("mine", np.array([[0.0, 77.0], [30, -90]]))
    assert_allclose(s.directions, [[0, 0], [30, 270]])


def _brute_force_duplicate(directions):
    v = direction_vector(directions[:, 0], directions[:, 1])
    close = angular_distance_deg(v[:, None, :], v[None, :, :]) < 1e-6
    np.fill_diagonal(close, False)
    return tuple(int(k) for k in np.argwhere(close)[0]) if close.any() else None


@given(
    st.lists(st.tuples(thetas, phis), min_size=1, max_size=40),
    st.lists(st.tuples(st.integers(0, 39), st.floats(-2e-6, 2e-6)), max_size=4),
)
def test_duplicates_found_as_the_pairwise_check_finds_them(base, copies):
    """Near-copies (within and beyond the 1e-6° tolerance) are named like the O(n²) check."""
    directions = list(base)
    for index, offset in copies:
        theta, phi = base[index % len(base)]
        directions.append((float(np.clip(theta + offset, 0.0, 90.0)), phi))
    directions = np.array(directions)
    expected = _brute_force_duplicate(np.where(directions[:, :1] == 0, [[0.0, 0.0]], directions))
    if expected is None:
        assert len(Sampling("mine", directions)) == len(directions)
    else:
        with pytest.raises(ConfigError, match=f"directions {expected[0]} and {expected[1]} are"):
            Sampling("mine", directions)


def test_sixty_thousand_directions_are_checked_without_a_pairwise_matrix():
    # A pairwise matrix of 60,000 directions needs 86 GB; the tree needs a few MB.
    rng = np.random.default_rng(3)
    directions = np.column_stack([rng.uniform(0, 90, 60_000), rng.uniform(0, 360, 60_000)])
    assert len(Sampling("dense", directions)) == 60_000
    directions[59_999] = directions[12]
    with pytest.raises(ConfigError, match="directions 12 and 59999 are the same"):
        Sampling("dense", directions)


def test_nearest_directions_exact_at_table_points():
    s = Sampling.named("H2")
    interp = nearest_directions(s.vectors, s.vectors, k=4)
    assert_allclose(interp.indices[:, 0], np.arange(81))
    assert_allclose(interp.weights[:, 0], 1.0)
    assert_allclose(interp.weights.sum(axis=1), 1.0)


@given(thetas, phis)
def test_interpolation_weights_are_a_partition_of_unity(theta, phi):
    table = Sampling.named("H1").vectors
    q = direction_vector(theta, phi)[None]
    for interp in (nearest_directions(table, q), barycentric_weights(table, q)):
        assert np.all(np.isfinite(interp.weights))
        assert np.all(interp.weights >= 0)
        assert_allclose(interp.weights.sum(), 1.0)


@given(thetas, phis)
def test_light_blends_carrying_the_cosine_interpolate_a_lambertian_plane_exactly(theta, phi):
    """Textures of cos θ_i (a Lambertian plane under each measured light) blend to the
    query's own cos θ, wherever the query lies; blends that sum to 1 do not."""
    table = Sampling.named("H1").vectors
    q = direction_vector(theta, phi)[None]
    for found in (nearest_directions(table, q), barycentric_weights(table, q)):
        weights = carry_light_cosine(found, table, q)
        assert np.all(np.isfinite(weights)) and np.all(weights >= 0)
        assert_allclose(weights @ table[found.indices[0], 2], q[:, 2], atol=1e-12)


def test_light_blends_carrying_the_cosine_are_exact_at_measured_lights_and_dark_at_the_horizon():
    table = Sampling.named("H1").vectors
    exact = nearest_directions(table, table, k=4)
    assert_allclose(carry_light_cosine(exact, table, table), exact.weights, atol=0)
    horizon = np.array([[0.6, 0.8, 0.0]])
    assert not carry_light_cosine(nearest_directions(table, horizon), table, horizon).any()
    # Between 15° and 45° the plain blend mixes cos 15° and cos 45° (3 % off cos 30°).
    rings = direction_vector(np.array([15.0, 45.0]), np.array([0.0, 0.0]))
    q = direction_vector(30.0, 0.0)[None]
    found = nearest_directions(rings, q, k=2)
    assert abs(found.weights @ rings[found.indices[0], 2] / q[0, 2] - 1) > 0.03
    # A measured light in the sample's plane gives no irradiance: divided by the floor.
    grazing = direction_vector(np.array([0.0, 90.0]), np.array([0.0, 0.0]))
    found = nearest_directions(grazing, direction_vector(89.9, 0.0)[None], k=2)
    weights = carry_light_cosine(found, grazing, direction_vector(89.9, 0.0)[None])
    assert np.all(np.isfinite(weights)) and weights.max() <= 1 / LIGHT_COSINE_FLOOR


def test_barycentric_reproduces_linear_functions_inside_a_triangle():
    # Barycentric weights in the gnomonic projection reproduce the query
    # direction up to scale: Σ w_i v_i ∥ q.
    table = Sampling.named("H2").vectors
    rng = np.random.default_rng(0)
    q = direction_vector(rng.uniform(0, 75, 50), rng.uniform(0, 360, 50))
    b = barycentric_weights(table, q)
    blended = np.einsum("mk,mkj->mj", b.weights, table[b.indices])
    assert_allclose(angular_distance_deg(blended, q), 0.0, atol=1e-6)
    exact = barycentric_weights(table, table)
    assert_allclose(np.max(exact.weights, axis=1), 1.0, atol=1e-9)


def test_spherical_triangulation_covers_the_hemisphere_once():
    """Each triangle's inverse undoes its corners; corners name table rows (mirrored below)."""
    table = Sampling.named("H1").vectors
    mesh = spherical_triangulation(table)
    corners_t = np.transpose(mesh.corners, (0, 2, 1))
    assert_allclose(mesh.inverse @ corners_t, np.broadcast_to(np.eye(3), corners_t.shape),
                    atol=1e-9)  # fmt: skip
    assert_allclose(np.abs(mesh.corners), np.abs(table[mesh.owner]), atol=1e-12)
    # Every upper-hemisphere direction lies in exactly one triangle (edges aside).
    rng = np.random.default_rng(1)
    q = direction_vector(rng.uniform(0, 90, 400), rng.uniform(0, 360, 400))
    inside = (np.einsum("tij,mj->mti", mesh.inverse, q).min(axis=2) > 1e-9).sum(axis=1)
    assert np.all(inside == 1)


def test_barycentric_degenerate_table():
    ring = direction_vector(np.full(8, 90.0), np.arange(8) * 45.0)
    with pytest.raises(ValueError, match="great circle"):
        barycentric_weights(ring, [[0, 0, 1]])


def test_texel_grid_orientation():
    g = texel_centers_mm(100, 4)
    assert g.shape == (4, 4, 2)
    assert_allclose(g[0, 0], [-37.5, 37.5])  # row 0 at +y, column 0 at -x
    assert_allclose(g[3, 3], [37.5, -37.5])
    with pytest.raises(ValueError, match="n ≥ 1"):
        texel_centers_mm(100, 0)
