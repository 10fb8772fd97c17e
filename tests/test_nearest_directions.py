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


@pytest.mark.parametrize("seed", range(6))
def test_nearest_other_is_the_k_d_trees_answer_to_the_last_bit(seed, monkeypatch):
    """``numerics.nearest_other`` compares every pair up to BRUTE_NEAREST_ROWS_UNLOADED points in a one-off process
    (sparing it SciPy's spatial import): the k-d tree's distances and indices exactly, on readings at random attitudes,
    quantized to 3 nT, and with near-copies 0.5 nT apart (the repeated attitudes the noise estimate looks for).  The
    tree is imported here, so the pairwise search is made to run up to that count."""
    from scipy.spatial import cKDTree

    from magbench import numerics
    from magbench.numerics import BRUTE_NEAREST_ROWS_UNLOADED, nearest_other

    monkeypatch.setattr(numerics, "BRUTE_NEAREST_ROWS", BRUTE_NEAREST_ROWS_UNLOADED)
    rng = np.random.default_rng(seed)
    n = int(rng.integers(2, BRUTE_NEAREST_ROWS_UNLOADED + 1)) if seed else 2
    points = rng.normal(0.0, 5e4, (n, 3))
    if seed % 2:
        points = np.round(points / 3.0) * 3.0
    if seed >= 3:
        half = n // 2
        points[:half] = points[half:2 * half] + rng.normal(0.0, 0.5, (half, 3))
    points = np.unique(points, axis=0)
    dist, idx = nearest_other(points)
    tree_dist, tree_idx = cKDTree(points).query(points, k=2)
    assert np.array_equal(dist, tree_dist[:, 1]) and np.array_equal(idx, tree_idx[:, 1])
    assert not np.any(idx == np.arange(len(points)))  # a point is never its own nearest


ONE_OFF = """
import sys
import numpy as np
from magbench.calibrators import make
rng = np.random.default_rng(0)
u = rng.normal(size=(300, 3))
u /= np.linalg.norm(u, axis=1)[:, None]
raw = 50000.0 * u * [1.02, 0.99, 1.01] + [150.0, -200.0, 80.0]  # no simulator: it imports SciPy's rotations
raw = np.repeat(raw, {reps}, axis=0)[:{n}] + rng.normal(0, 0.3, ({n}, 3))
before = "scipy.spatial" in sys.modules
make("lsq").fit(raw, f_ref_nT=50000.0)
print(before, "scipy.spatial" in sys.modules)
"""


@pytest.mark.parametrize("n, reps, imported", [(300, 1, False), (1200, 4, False), (4800, 16, False),
                                               (7200, 24, True)])
def test_a_record_without_times_is_judged_without_scipys_spatial_import(n, reps, imported):
    """A record without a t column has its repeated attitudes found by ``nearest_other``: in a fresh process up to
    BRUTE_NEAREST_ROWS_UNLOADED readings without importing scipy.spatial (0.1-0.2 s, half of a one-off ``calibrate``
    of 300 readings); the control, a record above it, does import it, so the check can fail."""
    import subprocess
    import sys

    out = subprocess.run([sys.executable, "-c", ONE_OFF.format(n=n, reps=reps)], capture_output=True, text=True,
                         check=True)
    assert out.stdout.split() == ["False", str(imported)]


@pytest.mark.parametrize("seed", range(4))
def test_the_revisit_mask_is_every_pair_closer_in_time_than_the_separation_or_in_one_hold(seed, monkeypatch):
    """The mask ``revisit_neighbours`` hands ``_nearest_directions`` (a band of columns found by searchsorted on the
    increasing positions) is the definition computed pair by pair: |position_i - position_j| < separation, or both
    rows in one hold; records longer than KNN_ROWS (a systematic sample) and shorter, in several blocks."""
    from magbench.calibrators import acceptance
    from magbench.numerics import systematic_rows

    rng = np.random.default_rng(seed)
    n, separation = int(rng.integers(300, 7000)), int(rng.integers(1, 80))
    raw = rng.normal(size=(n, 3)) * 5e4
    order = rng.permutation(n)
    holds = rng.integers(0, 5, n) if seed % 2 else None
    handed = []
    real = acceptance._nearest_directions

    def spy(readings, excluded, scale=None):
        handed.append(excluded)
        return real(readings, excluded, scale)

    monkeypatch.setattr(acceptance, "_nearest_directions", spy)
    acceptance.revisit_neighbours(raw, order, separation, holds)
    (excluded,) = handed
    position = np.arange(n)[systematic_rows(n, acceptance.KNN_ROWS)]
    hold = None if holds is None else holds[order[position]]
    for start in range(0, len(position), acceptance.KNN_BLOCK):
        block = slice(start, start + acceptance.KNN_BLOCK)
        expected = np.abs(position[block, None] - position[None, :]) < separation
        if hold is not None:
            expected |= hold[block, None] == hold[None, :]
        assert np.array_equal(excluded(block, len(position)), expected)
