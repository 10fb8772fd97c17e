"""The single-point residuals of a record that fits in one block (``ScalarObjective._residuals_one_block``, what
NLopt, RANSAC and every local method ask for) are the block-by-block reference form to the last bit."""
import numpy as np
import pytest

from magbench.calibrators.core import objective as objective_module
from magbench.calibrators.core.objective import ScalarObjective
from magbench.simulate import simulate
from magbench.simulate.sensor import PARAM_NAMES


def _point(rng, model):
    p = len(PARAM_NAMES[model])
    x = np.zeros(p)
    if model in ("nine", "angles"):
        x[:3] = rng.normal(0, 0.3, 3)
    if model == "nine":
        x[3:6] = rng.uniform(0.5, 1.5, 3)
        x[6:9] = rng.normal(0, 500, 3)
    if model == "offset":
        x[:] = rng.normal(0, 500, 3)
    if model == "diag":
        x[:3] = rng.uniform(0.5, 1.5, 3)
        x[3:] = rng.normal(0, 500, 3)
    return x


@pytest.mark.parametrize("scenario", ["sphere9", "lu2014", "vehicle9"])
@pytest.mark.parametrize("model", ["nine", "angles", "offset", "diag"])
def test_one_block_equals_the_blocks(scenario, model, monkeypatch):
    data = simulate(scenario, 3)
    obj = ScalarObjective(data.raw_nT, data.f_ref_nT, model)
    rng = np.random.default_rng(11)
    points = [_point(rng, model) for _ in range(30)]
    points.append(np.full(len(PARAM_NAMES[model]), np.nan))
    fast = [obj.residuals(x) for x in points]
    monkeypatch.setattr(objective_module, "CHUNK_ROWS", 7)  # the block-by-block form, 7 rows at a time
    slow = [obj.residuals(x) for x in points]
    for a, b in zip(fast, slow):
        assert np.array_equal(a, b, equal_nan=True)
    assert not np.array_equal(fast[0], fast[1])  # the negative control: other parameters, other residuals
    # and the form itself: |M (raw - o)| - F from the correction matrices, independently
    mat, o = objective_module.correction_matrices(points[0], model)
    direct = np.linalg.norm((data.raw_nT - o[0]) @ mat[0].T, axis=1) - data.f_ref_nT
    assert np.allclose(fast[0], direct, rtol=0, atol=1e-8)
