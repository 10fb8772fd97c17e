"""The nearest attitudes of the acceptance checks and the diagnosis (``acceptance._nearest_directions``): the k most
similar directions by ``k`` passes of argmax (``_most_similar``), checked against a full sort of each row."""
import numpy as np
import pytest

from magbench.calibrators.acceptance import (
    KNN_NEIGHBOURS,
    _most_similar,
    _nearest_directions,
    attitude_neighbours,
    revisit_neighbours,
)


def _reference(sims: np.ndarray, k: int) -> np.ndarray:
    """The k largest of each row by a stable sort (ties: the lower column first), in increasing column order."""
    return np.sort(np.argsort(-sims, axis=1, kind="stable")[:, :k], axis=1)


@pytest.mark.parametrize("seed", range(5))
@pytest.mark.parametrize("k", [1, 5, 9])
def test_most_similar_is_the_k_largest_in_column_order(seed, k):
    rng = np.random.default_rng(seed)
    sims = rng.uniform(-1, 1, (40, 70))
    assert np.array_equal(_most_similar(sims.copy(), k), _reference(sims, k))


def test_ties_go_to_the_lower_column():
    sims = np.zeros((3, 8))
    sims[:, [2, 5, 6]] = 0.5  # three tied best; two are asked for
    assert _most_similar(sims.copy(), 2).tolist() == [[2, 5]] * 3
    # and the tie at the boundary of the chosen set among equal values: the lowest columns
    assert _most_similar(np.zeros((2, 6)), 3).tolist() == [[0, 1, 2]] * 2


def test_excluded_pairs_are_chosen_only_when_too_few_are_left():
    rng = np.random.default_rng(1)
    readings = rng.normal(size=(30, 3))

    def all_but_three(block, m):  # every row may choose among columns 0, 1, 2 only
        near = np.ones((min(block.stop, m) - block.start, m), dtype=bool)
        near[:, :3] = False
        return near

    nearest, enough = _nearest_directions(readings, all_but_three)
    assert not enough.any()  # 3 < KNN_NEIGHBOURS: flagged
    for row in nearest:
        assert len(set(row.tolist())) == KNN_NEIGHBOURS  # no column twice
        assert {0, 1, 2} <= set(row.tolist())  # the allowed ones first

    def none(block, m):
        return np.zeros((min(block.stop, m) - block.start, m), dtype=bool)

    assert _nearest_directions(readings, none)[1].all()


def test_attitude_neighbours_against_brute_force_angles():
    """Each sampled reading's neighbours are the KNN_NEIGHBOURS other readings at the smallest angle from it (angles
    from arccos of the cosines, computed independently), and never the reading itself."""
    rng = np.random.default_rng(7)
    raw = rng.normal(size=(400, 3)) * 5e4
    rows, nearest = attitude_neighbours(raw)
    u = raw[rows] / np.linalg.norm(raw[rows], axis=1)[:, None]
    angle = np.arccos(np.clip(u @ u.T, -1, 1))
    np.fill_diagonal(angle, np.inf)
    expected = np.sort(np.argsort(angle, axis=1, kind="stable")[:, :KNN_NEIGHBOURS], axis=1)
    assert np.array_equal(nearest, expected)
    assert not np.any(nearest == np.arange(len(nearest))[:, None])


def test_revisits_are_away_in_time():
    """``revisit_neighbours``: on a path that passes the same directions twice, each neighbour is at least the
    separation away in time order (the negative control: the unconstrained nearest are the time neighbours)."""
    t = np.linspace(0, 2 * np.pi, 600)
    path = np.stack([np.cos(2 * t), np.sin(2 * t), 0.3 * np.sin(t)], axis=1) * 5e4  # the equator twice
    order = np.arange(len(path))
    found = revisit_neighbours(path, order, 32)
    assert found is not None
    rows, nearest, keep = found
    sampled = rows[keep]
    gap = np.abs(sampled[:, None] - rows[nearest])
    assert gap.min() >= 32
    free = attitude_neighbours(path)
    assert free is not None
    free_rows = np.arange(len(path))[free[0]]
    free_nearest = free[1]
    assert np.abs(free_rows[:, None] - free_rows[free_nearest]).min() < 32


@pytest.mark.parametrize("m", [4, 5, 6, 7, 300, 1201])
def test_leaving_out_itself_alone_is_the_mask_of_the_diagonal(m):
    """``excluded`` None (each reading's own row set, the attitude neighbours' case) chooses what the mask of the
    diagonal chooses, across KNN_BLOCK's blocks; negative control: a mask that leaves nothing out chooses the
    reading itself."""
    readings = np.random.default_rng(m).normal(size=(m, 3))  # 4 or 5 readings: too few left (``enough`` False)

    def diagonal(block, n):
        out = np.zeros((min(block.stop, n) - block.start, n), dtype=bool)
        out[np.arange(out.shape[0]), np.arange(block.start, block.start + out.shape[0])] = True
        return out

    mine, enough = _nearest_directions(readings, None)
    masked, enough_masked = _nearest_directions(readings, diagonal)
    assert np.array_equal(mine, masked) and np.array_equal(enough, enough_masked)
    assert enough.all() == (m - 1 >= KNN_NEIGHBOURS)
    kept, _ = _nearest_directions(readings, lambda block, n: np.zeros((min(block.stop, n) - block.start, n), bool))
    assert all(i in row for i, row in enumerate(kept.tolist()))
