"""The candidate grids hold every neighbour rig.geometry would choose.

The shader's choice is replayed here in numpy on the grid (rank a cell's
candidates, keep the best), for thousands of random directions, and compared
with ``nearest_directions`` / ``barycentric_weights`` on the whole table.
"""

import numpy as np
import pytest

from render import RenderError
from render.core.lookup import MAX_CANDIDATES, build_lookup, hemi_octahedral_cell
from rig.geometry import Sampling, barycentric_weights, nearest_directions


def random_directions(n: int, seed: int = 0) -> np.ndarray:
    q = np.random.default_rng(seed).normal(size=(n, 3))
    q[:, 2] = np.abs(q[:, 2])
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def chosen_by_grid(lookup, q: np.ndarray) -> np.ndarray:
    """(m, k) table indices the shader picks for directions q, sorted."""
    cells = hemi_octahedral_cell(q, lookup.resolution)
    candidates = lookup.candidates[cells[:, 1], cells[:, 0]]
    picked = []
    for qi, cand in zip(q, candidates, strict=True):
        if lookup.method == "barycentric":
            rows = lookup.table.reshape(-1, 3, 4)[cand].astype(np.float64)
            weights = rows[:, :, :3] @ qi
            best = int(np.argmax(weights.min(axis=1)))
            picked.append(rows[best, :, 3].astype(int))
        else:
            cosine = lookup.table[cand, :3].astype(np.float64) @ qi
            picked.append(cand[np.argsort(-cosine, kind="stable")[: lookup.k]])
    return np.sort(np.array(picked), axis=1)


TABLES = {
    "H1": Sampling.named("H1").vectors,
    "H2 every third": Sampling.named("H2").vectors[::3],
    "five": Sampling("five", np.array([[0, 0], [50, 0], [50, 90], [50, 180], [50, 270]])).vectors,
}


@pytest.mark.parametrize("table", TABLES)
@pytest.mark.parametrize("method", ["nearest", "nearest4", "barycentric"])
def test_grid_candidates_contain_the_cpu_neighbours(table, method):
    vectors = TABLES[table]
    lookup = build_lookup(vectors, method)
    assert lookup.length <= MAX_CANDIDATES
    q = random_directions(3000)
    if method == "barycentric":
        expected = barycentric_weights(vectors, q).indices
    else:
        expected = nearest_directions(vectors, q, k=lookup.k).indices
    np.testing.assert_array_equal(chosen_by_grid(lookup, q), np.sort(expected, axis=1))


@pytest.mark.parametrize("method", ["nearest", "nearest4", "barycentric"])
def test_a_table_direction_is_among_its_own_candidates(method):
    """At a measured direction only that direction has weight (the others may tie)."""
    vectors = TABLES["H1"]
    lookup = build_lookup(vectors, method)
    cells = hemi_octahedral_cell(vectors, lookup.resolution)
    candidates = lookup.candidates[cells[:, 1], cells[:, 0]]
    if method == "barycentric":
        owners = lookup.table.reshape(-1, 3, 4)[:, :, 3].astype(int)
        candidates = [owners[c[c >= 0]].ravel() for c in candidates]
    assert all(i in c for i, c in enumerate(candidates))


@pytest.mark.parametrize("method", ["nearest4", "barycentric"])
def test_every_cell_lists_distinct_candidates_ascending_and_its_texels_hold_them(method):
    """The shader reads L candidates from every cell with no end marker, in index order (ties
    go to the lower index), candidate i's texel j from layer i·m + j."""
    lookup = build_lookup(TABLES["H2 every third"], method)
    cand = lookup.candidates
    assert cand.min() >= 0 and np.all(np.diff(cand, axis=2) > 0)
    per = 3 if method == "barycentric" else 1
    texels = lookup.cell_texels()
    assert texels.shape == (lookup.length * per, lookup.resolution, lookup.resolution, 4)
    row, col = 17, lookup.resolution // 2
    expected = lookup.table.reshape(-1, per, 4)[cand[row, col]].reshape(-1, 4)
    np.testing.assert_array_equal(texels[:, row, col], expected)


def test_index_keeps_the_slots_own_numbers():
    """A view table without its empty slots still names the slots by their numbers."""
    vectors = TABLES["H1"]
    kept = np.flatnonzero(np.arange(len(vectors)) % 5 != 2)
    lookup = build_lookup(vectors[kept], "nearest4", index=kept)
    q = random_directions(500, seed=1)
    expected = kept[nearest_directions(vectors[kept], q, k=4).indices]
    np.testing.assert_array_equal(chosen_by_grid(lookup, q), np.sort(expected, axis=1))


def test_bad_method_and_degenerate_table_are_named():
    with pytest.raises(RenderError, match="'cubic'"):
        build_lookup(TABLES["H1"], "cubic")
    ring = Sampling("ring", np.array([[90, 0], [90, 120], [90, 240]])).vectors
    with pytest.raises(RenderError, match=r"barycentric.*nearest4"):
        build_lookup(ring, "barycentric")
