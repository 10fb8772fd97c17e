"""``model="auto"``'s count of distinct attitudes: the pairwise path (a one-off process, up to BRUTE_NEAREST_ROWS
readings) gives the k-d tree's count on random, held, slow-path, quantized and copied readings; a one-off
``calibrate --model auto`` then imports neither scipy.spatial nor scipy.sparse, the control above the limit does."""
import subprocess
import sys

import numpy as np
import pytest
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from magbench.calibrators import modelselect


def tree_count(points: np.ndarray, radius: float) -> int:
    pairs = cKDTree(points).query_pairs(radius, output_type="ndarray")
    n = len(points)
    if len(pairs) == 0:
        return n
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    return int(connected_components(graph, directed=False)[0])


def readings(kind: str, n: int, rng) -> np.ndarray:
    u = rng.normal(size=(n, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    if kind == "random":
        return u * 5e4 + rng.normal(size=(n, 3)) * 2
    if kind == "held":
        c = u[:max(1, n // 20)]
        return c[rng.integers(0, len(c), n)] * 5e4 + rng.normal(size=(n, 3)) * 5
    if kind == "slow-path":  # consecutive readings 0-60 nT apart: chains
        ang = np.cumsum(rng.uniform(0.0, 0.0012, n))
        return np.column_stack([np.cos(ang), np.sin(ang), np.zeros(n)]) * 5e4
    if kind == "quantized":  # distances of exactly the radius
        return np.round(u * 5e4 / 50.0) * 50.0 + rng.integers(0, 2, (n, 3)) * 50.0
    return np.repeat(u[:max(1, n // 3)] * 5e4, 3, axis=0)[:n]  # copies


@pytest.mark.parametrize("kind", ["random", "held", "slow-path", "quantized", "copies"])
def test_pairwise_count_is_the_trees(kind):
    rng = np.random.default_rng(len(kind))
    for n in (1, 2, 3, 17, 120, 700):
        points = readings(kind, n, rng)
        assert modelselect._linked_groups(points, 50.0) == tree_count(points, 50.0), (kind, n)


AUTO = """
import contextlib, io, sys
from magbench.benchmarks.cli import main
with contextlib.redirect_stdout(io.StringIO()):
    code = main(["calibrate", {path!r}, "--method", "lsq", "--model", "auto", "--json"])
print(code, "scipy.spatial" in sys.modules, "scipy.sparse" in sys.modules)
"""


@pytest.mark.parametrize("n, loaded", [(300, False), (2500, True)], ids=["300", "control-2500"])
def test_a_one_off_auto_model_skips_the_tree(tmp_path, n, loaded):
    rng = np.random.default_rng(n)
    u = rng.normal(size=(n, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    raw = u * 5e4 @ np.array([[1.01, 0.0, 0.0], [0.01, 0.99, 0.0], [0.0, 0.02, 1.0]]).T + [150.0, -80.0, 40.0]
    raw += rng.normal(size=(n, 3)) * 2
    path = tmp_path / "r.csv"
    np.savetxt(path, np.column_stack([np.arange(n) * 0.1, raw, np.full(n, 5e4)]), delimiter=",",
               header="t,bx,by,bz,f_ref", comments="")
    out = subprocess.run([sys.executable, "-c", AUTO.format(path=str(path))], capture_output=True, text=True,
                         check=True)
    code, spatial, sparse = out.stdout.split()
    assert code in ("0", "3")
    assert (spatial, sparse) == (str(loaded), str(loaded))
